"""Scene -> MJCF text: the MuJoCo model of a scene, holding only what the scene uses.

``to_mjcf(scene)`` writes the scene's layout (rbody.layout.Layout) as one MJCF document:

- the joints the scene uses (hinge, slide, ball, free, roll), bodies nested along ``Body.parent``, each body at
  its reference pose (every hinge and slide coordinate zero, as in rbody);
- explicit mass properties from rbody's Inertia: ``<inertial pos mass fullinertia="Ixx Iyy Izz Ixy
  Ixz Iyz">`` about the centre of mass in the body frame, with ``inertiafromgeom="false"`` so that no
  geom ever changes a mass;
- geoms from the Shapes, all with contype = conaffinity = 0, and one ``<pair>`` per Contact: nothing
  collides except the pairs the scene lists, each with its own condim, friction, solref and solimp;
- gravity (0, 0, -g) (0 for a scene whose class sets applies_gravity = False), the time step,
  the integrator, and the initial state as keyframe "initial" (free joints: qvel = (v of the
  body-frame origin, world; omega in the BODY frame), MuJoCo's order).

Numbers are written with repr (17 significant digits): the model holds rbody's float64 values exactly.

What MuJoCo would refuse is refused here first, with a ValueError naming the value and the rule:

- MuJoCo needs every principal moment of a moving body >= 1e-14 kg m^2 (its fullinertia check; moving
  bodies also need >= 1e-15). A zero moment (thin rod, point mass) is raised, and the XML comment says
  so: to ``min_inertia`` when the caller gives it (then every moment below it is raised); otherwise to
  the moment, about that principal axis, of the body's thickest shape given the body's whole mass (the
  rod's capsule, about the rod's axis). With neither, ValueError.
- MuJoCo checks A + B >= C on its own eigenvalues with no tolerance. Measured (mujoco 4.0): the full
  tensor of a turned hoop or disc (A + B = C exactly) is refused about 40 % of the time, by round-off.
  A body within round-off of A + B = C is therefore written in its principal form
  (``quat`` + ``diaginertia``, rbody's eigen-decomposition) with C set to A + B where round-off put it
  above; beyond round-off, ValueError.
- Names: MuJoCo takes any text, but not an empty name where a name is referenced, not two bodies,
  joints or geoms (shapes) of one name, not a body called "world". Control characters are refused too
  (XML cannot carry most of them).
- Sizes > 0 for every geom, planes only on the world, free joints only on bodies whose parent is the
  world and with no other joint.

Contacts (defaults; every one can be overridden):

- restitution e = 1 (elastic impacts): a stiff undamped spring of reference stiffness K = (1/dt)^2,
  solref = (-K, 0) (direct form), solimp = (0.99, 0.99, 0.001): the contact lasts a fixed few steps,
  and with the Euler integrator the velocity comes back exactly reversed (measured: energy after 31
  impacts within 5e-13). Integrator Euler for scenes with impacts.
- 0 < e < 1: a spring-damper that lasts IMPACT_STEPS = 30 steps, K = (pi / (30 dt))^2, solref =
  (-K, -B), B = 2 zeta sqrt(K / 0.99), with zeta the damping ratio whose restitution is e for a linear
  spring-damper that can push but not pull (the contact ends when K x + B x' = 0, not at x = 0):
  impact_damping_ratio(e). A damper on the stiff spring above does not work: the impact is then over
  in one or two steps and its outcome depends on where in a step the bodies meet (measured e = 0.15 to
  0.81 for e = 0.25). Measured with these settings (dt = 1e-3, head-on pair, five contact phases):
  e = 0.25 -> 0.225..0.249, 0.5 -> 0.482..0.501, 0.9 -> 0.897..0.901; the contact sinks v N dt / pi
  deep (1 cm at 1 m/s).
- e = 0 (resting, rolling): a critically damped contact of time constant 2 dt, solref = (2 dt, 1),
  the stiffest MuJoCo allows at that step, and solimp = (0.99, 0.99, 0.001). With MuJoCo's defaults
  (0.02, 1) and (0.9, 0.95, 0.001) a rolling body sinks ~0.1 mm into the slope and rolls on a radius
  short by that much: measured slip -delta phi', x off by 4e-4 m after 1 s; with these, 4e-7 m.
- friction mu = 0: condim 1 (normal force only); mu > 0: condim 3 with friction (mu, mu), the cone
  elliptic and impratio 100 (soft friction trades force for slip; impratio makes it stiffer); a contact's
  condim 4 or 6 as it is, with friction (mu, mu, torsion, rolling, rolling).
- Scenes without impacts default to the RK4 integrator.

Roll joints (rolling without slipping, one coordinate q: rbody.layout.Joint). MuJoCo has no joint that
ties a translation to a rotation, so a roll joint of radius a, axis w and surface normal e is written as
two joints, in this order, and a joint equality between them:

- slide ``<name>_slide`` along l = w x e (body frame), ref a * ref: the body slides by a (q - ref) first;
- hinge ``<name>`` about w through the anchor, with the roll joint's ref, damping, stiffness, springref and
  armature (rbody applies them to q, which is the hinge's coordinate);
- ``<equality><joint joint1="<name>_slide" joint2="<name>" polycoef="0 a 0 0 0"/>``: slide - a ref =
  a (hinge - ref), i.e. slide = a hinge, the rolling condition v_centre = a q' l. MuJoCo keeps it as a soft
  constraint solved every step, at its stiffest: solref (2 dt, 1) (time constant 2 dt, critically damped,
  the least MuJoCo allows at that step) and solimp EQUALITY_SOLIMP (impedance 0.9999 at any violation).
  With MuJoCo's defaults (0.02 s; 0.9, 0.95) a rolling disc slips by ~0.09 m/s and its distance stays
  2.5e-3 m off at every dt (validation.bench.reduced). The initial state: slide a q0, hinge q0 (and
  a q0', q0'). The constraint solver must then stay on (validation.backends.mujoco.disable_unused turns
  it off only for a model with no equality).
"""

from __future__ import annotations

import math
import os
import textwrap
from dataclasses import dataclass
from typing import Iterable, Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

from rbody.checks import finite_array, in_interval, one_of, positive
from rbody.inertia import Inertia
from rbody.motion import quat_from_matrix, quat_normalize, quat_to_matrix
from rbody.layout import WORLD, depth_first, joint_order, Body, Contact, Joint, Layout, Shape, already_unit
from rbody.scene import Scene
from rbody.mjcf import actuators as mjcf_actuators

DEFAULT_TIMESTEP = 0.002            # MuJoCo's own default step [s], used when dt is not given
MUJOCO_MIN_MOMENT = 1e-14           # MuJoCo refuses a fullinertia whose smallest eigenvalue is below (mjEPS)
MUJOCO_MIN_MASS = 1e-15             # ... and a moving body lighter than mjMINVAL [kg]
MUJOCO_MAX_MOMENT = 1e300           # moments beyond this overflow when summed (compiler, A + B >= C)
ZERO_MOMENT_RTOL = 1e-12            # a principal moment below this fraction of the largest is zero (round-off)
TRIANGLE_RTOL = 1e-12               # A + B - C within this fraction of C is "on the boundary" (round-off)
CONTACT_SOLIMP = (0.99, 0.99, 0.001)  # impedance d = 0.99 at any depth: the contact follows its reference spring
IMPACT_STEPS = 30                   # inelastic impacts (0 < e < 1) last about this many steps
RESTING_TIMECONST_STEPS = 2.0       # resting contacts: time constant 2 dt, the stiffest MuJoCo allows (refsafe)
EQUALITY_TIMECONST_STEPS = 2.0      # roll joints' equality: time constant 2 dt, critically damped (as above)
EQUALITY_SOLIMP = (0.9999, 0.9999, 0.001)  # roll joints' equality: impedance 0.9999, MuJoCo's largest below 1
ROLL_SLIDE_SUFFIX = "_slide"        # a roll joint <name> is written as slide <name>_slide and hinge <name>
FRICTION_IMPRATIO = 100.0
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
CONES = ("pyramidal", "elliptic")
CONDIMS = (1, 3, 4, 6)
INITIAL_KEY = "initial"

_SIZE_COUNT = {"sphere": 1, "cylinder": 2, "capsule": 2, "box": 3, "plane": 2, "ellipsoid": 3, "mesh": 0,
               "hfield": 4}
_MJCF_JOINT = {"hinge": "hinge", "slide": "slide", "ball": "ball", "free": "free", "roll": "hinge"}
_JOINT_ATTRIBUTES = ("damping", "stiffness", "springref", "armature", "ref")  # written only when non-zero


# ----- mass properties as MuJoCo will hold them --------------------------------------------------------

@dataclass(frozen=True)
class ExportedInertia:
    """The mass properties to_mjcf writes for one body.

    inertia: mass [kg], com (3,) [m] and tensor (3,3) [kg m^2] as written (body frame, about the com)
    moments: (3,) principal moments ascending [kg m^2]; axes (3,3) their directions as columns
    form:    "full" (fullinertia) or "principal" (quat + diaginertia, for bodies on A + B = C)
    note:    what was raised and why ("" when the body is written exactly as rbody holds it)
    """

    inertia: Inertia
    moments: np.ndarray
    axes: np.ndarray
    form: str
    note: str = ""


def shape_inertia(shape: Shape, mass: float) -> Inertia | None:
    """Inertia (3,3 about the shape's own centre, body axes) of `shape` as a uniform solid of `mass` [kg];
    None for a plane. Used only to give a zero principal moment a thickness."""
    size = shape.size
    if shape.kind == "plane":
        return None
    if shape.kind == "sphere":
        local = Inertia.solid_sphere(mass, size[0])
    elif shape.kind == "cylinder":
        local = Inertia.solid_cylinder(mass, size[0], 2 * size[1], "z")
    elif shape.kind == "capsule":
        local = Inertia(mass, np.zeros(3), _capsule_tensor(mass, size[0], size[1]))
    elif shape.kind == "box":
        local = Inertia.box(mass, 2 * np.asarray(size))
    elif shape.kind == "ellipsoid":  # m (b^2 + c^2) / 5, ...
        a, b, c = (float(s) ** 2 for s in size[:3])
        local = Inertia(mass, np.zeros(3), np.diag([b + c, a + c, a + b]) * mass / 5)
    elif shape.vertices and not shape.mesh:  # a mesh given by its points: their convex hull as a uniform solid
        import trimesh

        local = Inertia.from_mesh(trimesh.Trimesh(np.asarray(shape.vertices)).convex_hull, mass=mass)
    else:  # mesh: vertices in the body frame already
        return Inertia.from_mesh(shape.mesh, mass=mass)
    return local.rotated(np.asarray(shape.quat))


def _capsule_tensor(mass: float, radius: float, half: float) -> np.ndarray:
    """Solid capsule along z: cylinder of half length h plus two hemispheres of radius r, mass by volume.

    About z: m_c r^2/2 + 2/5 m_s r^2. Across: m_c (3 r^2 + 4 h^2)/12 + m_s (2 r^2/5 + h^2 + 3 h r/4)
    (each hemisphere's centroid is 3r/8 beyond the cylinder's end)."""
    cylinder_volume, sphere_volume = 2 * math.pi * radius**2 * half, 4 / 3 * math.pi * radius**3
    m_c = mass * cylinder_volume / (cylinder_volume + sphere_volume)
    m_s = mass - m_c
    along = m_c * radius**2 / 2 + 0.4 * m_s * radius**2
    across = m_c * (3 * radius**2 + 4 * half**2) / 12 + m_s * (0.4 * radius**2 + half**2 + 0.75 * half * radius)
    return np.diag([across, across, along])


def exported_inertia(body: Body, *, min_inertia: float | None = None) -> ExportedInertia:
    """The mass properties `to_mjcf` writes for `body` (see the module docstring for the rules).

    Raises ValueError when MuJoCo would refuse the body and no rule applies.
    """
    inertia = body.inertia
    if inertia.mass < MUJOCO_MIN_MASS:
        raise ValueError(f"body {body.name!r}: mass={inertia.mass!r} kg is below MuJoCo's least mass of a moving "
                         f"body ({MUJOCO_MIN_MASS} kg); give the scene in units where the mass is larger")
    moments, axes = inertia.principal()
    moments = moments.copy()
    largest = float(moments[-1])
    notes = []
    if min_inertia is not None:
        floor = positive(min_inertia, "min_inertia")
        if floor > MUJOCO_MAX_MOMENT:
            raise ValueError(f"min_inertia={min_inertia!r} kg m^2: beyond {MUJOCO_MAX_MOMENT:g}, where sums of moments "
                             "(MuJoCo's compiler, the triangle inequality) overflow float64; use larger units")
        if floor < MUJOCO_MIN_MOMENT:
            raise ValueError(f"min_inertia={min_inertia!r} kg m^2: MuJoCo needs every principal moment "
                             f">= {MUJOCO_MIN_MOMENT} kg m^2, so the floor must be at least that")
        low = moments < floor
        if np.any(low):
            notes.append(f"principal moments {_fmt(moments[low])} kg m^2 raised to min_inertia={floor!r}")
            moments[low] = floor
    else:
        zero = (moments <= ZERO_MOMENT_RTOL * largest) | (moments < MUJOCO_MIN_MOMENT)
        if np.any(zero):
            solids = [(shape, shape_inertia(shape, inertia.mass)) for shape in body.shapes]
            solids = [(shape, solid) for shape, solid in solids if solid is not None]
            if not solids:
                raise ValueError(
                    f"body {body.name!r} has principal moments {_fmt(moments)} kg m^2: MuJoCo needs every "
                    f"principal moment >= {MUJOCO_MIN_MOMENT} kg m^2 (a thin rod or a point mass has none about "
                    "some axis) and the body has no shape to give it a thickness; pass min_inertia=... "
                    "(each principal moment is then raised to at least it) or give the body a shape")
            for i in np.flatnonzero(zero):
                axis = axes[:, i]
                values = [float(axis @ solid.tensor @ axis) for _shape, solid in solids]
                best = int(np.argmax(values))
                if not values[best] >= MUJOCO_MIN_MOMENT:
                    raise ValueError(
                        f"body {body.name!r}: its principal moment about {_fmt(axis)} is {moments[i]!r} kg m^2 "
                        f"and its shapes give at most {values[best]!r} kg m^2 about that axis, below MuJoCo's "
                        f"least {MUJOCO_MIN_MOMENT} kg m^2; pass min_inertia=...")
                notes.append(f"principal moment {float(moments[i])!r} kg m^2 about {_fmt(axis)} raised to "
                             f"{values[best]!r} kg m^2, the moment of shape {solids[best][0].name!r} "
                             "(a uniform solid of the body's mass) about that axis")
                moments[i] = values[best]
    order = np.argsort(moments, kind="stable")
    moments, axes = moments[order], axes[:, order]
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    a, b, c = (float(x) for x in moments)
    margin = a + b - c
    if margin < -TRIANGLE_RTOL * c:
        raise ValueError(f"body {body.name!r}: principal moments {_fmt(moments)} kg m^2 break the triangle "
                         f"inequality A + B >= C by {-margin!r} kg m^2, beyond round-off; MuJoCo refuses them")
    raised = bool(notes)
    if margin <= TRIANGLE_RTOL * c:
        # On A + B = C (hoop, disc, plate): write rbody's principal form, with C no larger than A + B.
        if a + b < c:
            moments[2] = a + b
        form = "principal"
        tensor = axes @ np.diag(moments) @ axes.T
        tensor = 0.5 * (tensor + tensor.T)
        if not raised:
            tensor = inertia.tensor  # the body itself; only its decomposition is written
    else:
        form = "full"
        tensor = axes @ np.diag(moments) @ axes.T if raised else inertia.tensor
        tensor = 0.5 * (tensor + tensor.T)
    written = Inertia(inertia.mass, inertia.com, tensor)
    return ExportedInertia(written, moments, axes, form, "; ".join(notes))


# ----- contacts -------------------------------------------------------------------------------------

def contact_parameters(contact: Contact, dt: float, *, solref: Sequence[float] | None = None,
                       solimp: Sequence[float] | None = None, condim: int | None = None) -> dict:
    """The <pair> settings of one Contact at step dt [s]: condim, friction (5,), solref (2,), solimp (3|5,)."""
    e, mu = contact.restitution, contact.friction
    if e == 1:
        default_solref = (-1.0 / dt**2, 0.0)
    elif e > 0:
        stiffness = (math.pi / (IMPACT_STEPS * dt)) ** 2
        default_solref = (-stiffness, -2 * impact_damping_ratio(e) * math.sqrt(stiffness / CONTACT_SOLIMP[1]))
    else:
        default_solref = (RESTING_TIMECONST_STEPS * dt, 1.0)  # critically damped
    default_solimp = CONTACT_SOLIMP
    frictionless = contact.condim == 1 or mu + contact.torsion + contact.rolling == 0  # rbody's CONTACT1
    return {
        "condim": (1 if frictionless else contact.condim) if condim is None else condim,
        "friction": (mu, mu, contact.torsion, contact.rolling, contact.rolling),
        "solref": tuple(default_solref if solref is None else solref),
        "solimp": tuple(default_solimp if solimp is None else solimp),
    }


def pushing_restitution(zeta: float) -> float:
    """Restitution [-] of x'' + 2 zeta w x' + w^2 x = 0 entered at x = 0, x' = v0, ending when the force
    w^2 x + 2 zeta w x' falls to 0 (a contact pushes, never pulls): -x'(end) / v0.

    Underdamped (s = sqrt(1 - zeta^2)): the force vanishes at w t = phi / s, phi = pi - atan2(2 zeta s,
    1 - 2 zeta^2), and e = exp(-zeta phi / s) |cos(phi) - zeta sin(phi) / s|. Overdamped (s = sqrt(zeta^2 - 1),
    r = -zeta +- s): e^((r1 - r2) w t) = (1 + 2 zeta r2) / (1 + 2 zeta r1). Critical: e^-2."""
    if zeta == 1:
        return math.exp(-2.0)  # critical: x = t e^-t, the force (2 - t) e^-t vanishes at w t = 2
    if zeta < 1:
        s = math.sqrt(1 - zeta * zeta)
        phi = math.pi - math.atan2(2 * zeta * s, 1 - 2 * zeta * zeta)
        return math.exp(-zeta * phi / s) * abs(math.cos(phi) - zeta / s * math.sin(phi))
    s = math.sqrt(zeta * zeta - 1)
    r1, r2 = -zeta + s, -zeta - s
    t = math.log((1 + 2 * zeta * r2) / (1 + 2 * zeta * r1)) / (2 * s)
    return abs(r1 * math.exp(r1 * t) - r2 * math.exp(r2 * t)) / (2 * s)


def impact_damping_ratio(e: float) -> float:
    """zeta [-] with pushing_restitution(zeta) = e, for 0 < e < 1 (bisection; e falls as zeta grows)."""
    e = in_interval(e, "restitution", 0.0, 1.0)
    low, high = 0.0, 100.0  # pushing_restitution(100) = 2.5e-5
    if pushing_restitution(high) > e:
        raise ValueError(f"restitution={e!r}: below {pushing_restitution(high):.3g}, the least a contact spring-"
                         "damper gives here; use 0 (a resting contact)")
    for _ in range(200):
        middle = 0.5 * (low + high)
        if pushing_restitution(middle) > e:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def has_impacts(layout: Layout) -> bool:
    """True when some contact has restitution > 0 (an impact, which MuJoCo resolves as a stiff spring)."""
    return any(contact.restitution > 0 for contact in layout.contacts)


# ----- structure ---------------------------------------------------------------------------------------

def body_order(layout: Layout) -> tuple[Body, ...]:
    """Bodies in MuJoCo's order: rbody.layout.depth_first (the one tree order)."""
    return depth_first(layout)


def initial_state(layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's qpos (nq,) and qvel (nv,) of the scene's initial state.

    hinge/slide: qpos0 [rad | m], qvel0 [rad/s | m/s]; free: qpos = (pos (3,), quat (4,)) of the body,
    qvel = (v (3,) of the body-frame origin, world; omega (3,) in the BODY frame, R^T omega_world);
    roll (two MuJoCo joints, see the module docstring): slide a q0 [m] then hinge q0 [rad], rates a q0', q0'.
    """
    bodies = {body.name: body for body in layout.bodies}
    qpos, qvel = [], []
    for joint in joint_order(layout):
        if joint.kind == "free":
            body = bodies[joint.body]
            quat = _unit_quat(body.quat)
            velocity = _free_velocity(joint)
            qpos.extend(list(body.pos) + quat.tolist())
            qvel.extend(velocity[0].tolist() + (quat_to_matrix(quat).T @ velocity[1]).tolist())
        elif joint.kind == "ball":  # quaternion (0.0: identity); body-frame angular velocity (0.0: at rest)
            quat = np.atleast_1d(np.asarray(joint.qpos0, dtype=float))
            quat = np.array([1.0, 0.0, 0.0, 0.0]) if quat.size == 1 and quat[0] == 0 else _unit_quat(quat)
            omega = np.atleast_1d(np.asarray(joint.qvel0, dtype=float))
            omega = np.zeros(3) if omega.size == 1 and omega[0] == 0 else finite_array(
                omega, f"joint {joint.name!r}: qvel0", shape=(3,))
            qpos.extend(quat.tolist())
            qvel.extend(omega.tolist())
        elif joint.kind == "roll":  # slide = a q, hinge = q (the equality's reference)
            angle = float(joint.qpos0)
            rate = float(finite_array(joint.qvel0, f"joint {joint.name!r}: qvel0", shape=()))
            qpos.extend([joint.radius * angle, angle])
            qvel.extend([joint.radius * rate, rate])
        else:
            qpos.append(float(joint.qpos0))
            qvel.append(float(finite_array(joint.qvel0, f"joint {joint.name!r}: qvel0", shape=())))
    return np.array(qpos, dtype=float), np.array(qvel, dtype=float)


def _unit_quat(quat) -> np.ndarray:
    """(4,) the quaternion, normalised only when it is not already unit to 2 eps (rbody.layout.already_unit)."""
    quat = np.asarray(quat, dtype=float)
    return quat if already_unit(quat) else quat_normalize(quat)


def _free_velocity(joint: Joint) -> np.ndarray:
    """(2, 3): v of the body-frame origin and omega, world frame, from a free joint's qvel0 (0 = at rest)."""
    velocity = finite_array(joint.qvel0, f"joint {joint.name!r}: qvel0")
    if velocity.size == 6:
        return velocity.reshape(2, 3)
    if velocity.size == 1 and float(velocity) == 0.0:
        return np.zeros((2, 3))
    raise ValueError(f"joint {joint.name!r}: a free joint's qvel0={joint.qvel0!r} must be (v (3,), omega (3,)) "
                     "in the world frame [m/s, rad/s]")


def _check_layout(layout: Layout) -> None:
    """Everything MuJoCo would refuse about names and structure, as ValueErrors."""
    _unique("body", [b.name for b in layout.bodies])
    _unique("joint", [j.name for j in layout.joints]
            + [j.name + ROLL_SLIDE_SUFFIX for j in layout.joints if j.kind == "roll"])
    shapes = list(layout.fixed) + [s for b in layout.bodies for s in b.shapes]
    _unique("shape", [s.name for s in shapes])
    _unique("tendon", [t.name for t in layout.tendons])
    _unique("actuator", [a.name for a in layout.actuators])
    if any(b.name == WORLD for b in layout.bodies):
        raise ValueError(f"a body is called {WORLD!r}: MuJoCo reserves that name for the world body")
    names = {b.name for b in layout.bodies}
    for body in layout.bodies:
        if body.parent != WORLD and body.parent not in names:
            raise ValueError(f"body {body.name!r}: parent={body.parent!r} is neither {WORLD!r} nor a body of the scene")
        finite_array(body.pos, f"body {body.name!r}: pos", shape=(3,))
        finite_array(body.quat, f"body {body.name!r}: quat", shape=(4,))
    reached = {b.name for b in body_order(layout)}
    if reached != names:
        raise ValueError(f"bodies {sorted(names - reached)} are not reached from the world: their parents "
                         "form a loop")
    for joint in layout.joints:
        if joint.body not in names:
            raise ValueError(f"joint {joint.name!r}: body={joint.body!r} is not a body of the scene")
    moving = set()
    for body in body_order(layout):
        own = [j for j in layout.joints if j.body == body.name]
        if own or body.parent in moving:
            moving.add(body.name)
        if any(j.kind == "free" for j in own):
            if body.parent != WORLD:
                raise ValueError(f"body {body.name!r} has a free joint but its parent is {body.parent!r}: MuJoCo "
                                 "allows free joints only on children of the world")
            if len(own) > 1:
                raise ValueError(f"body {body.name!r} has a free joint and {len(own) - 1} other joints: a free "
                                 "joint must be the body's only joint")
        if sum({"free": 6, "ball": 3, "roll": 2}.get(j.kind, 1) for j in own) > 6:
            raise ValueError(f"body {body.name!r} has {len(own)} joints: MuJoCo allows at most 6 degrees of freedom "
                             "per body")
        for shape in body.shapes:
            if shape.kind == "plane" and body.name in moving:
                raise ValueError(f"shape {shape.name!r} is a plane on the moving body {body.name!r}: MuJoCo allows "
                                 "planes only on the world (Layout.fixed) or on bodies without joints")
    for shape in shapes:
        _check_shape(shape)
    shape_names = {s.name for s in shapes}
    for contact in layout.contacts:
        for name in (contact.shape_a, contact.shape_b):
            if name not in shape_names:
                raise ValueError(f"contact ({contact.shape_a!r}, {contact.shape_b!r}): {name!r} is not a shape of "
                                 "the scene")
        if contact.shape_a == contact.shape_b:
            raise ValueError(f"contact ({contact.shape_a!r}, {contact.shape_b!r}): a shape cannot touch itself")


def _unique(kind: str, names: list[str]) -> None:
    seen = set()
    for name in names:
        if not isinstance(name, str) or not name:
            raise ValueError(f"a {kind} has name {name!r}: MuJoCo needs a non-empty name to refer to it")
        bad = [c for c in name if ord(c) < 32 or ord(c) == 127]
        if bad:
            raise ValueError(f"{kind} name {name!r} contains control characters {bad!r}: XML cannot carry them "
                             "in a MuJoCo name")
        if name in seen:
            raise ValueError(f"two {kind}s are called {name!r}: MuJoCo needs unique {kind} names")
        seen.add(name)


def _check_shape(shape: Shape) -> None:
    count = _SIZE_COUNT[shape.kind]
    if len(shape.size) != count and not (shape.kind == "plane" and len(shape.size) == 3):
        raise ValueError(f"shape {shape.name!r}: a {shape.kind} has {count} sizes, got size={shape.size!r}")
    if shape.kind == "plane":
        return
    if any(s <= 0 for s in shape.size):
        raise ValueError(f"shape {shape.name!r}: size={shape.size!r}: MuJoCo needs every size of a {shape.kind} "
                         "> 0 [m]")
    if shape.kind == "mesh" and not shape.mesh and not shape.vertices:
        raise ValueError(f"shape {shape.name!r}: a mesh shape needs its file (Shape.mesh) or its vertices "
                         "(Shape.vertices)")


# ----- writing ------------------------------------------------------------------------------------------

def _num(x: float) -> str:
    """float64 written so that it reads back exactly (repr: shortest round-trip, up to 17 digits)."""
    return repr(float(x))


def _vec(values: Iterable[float]) -> str:
    return " ".join(_num(v) for v in values)


def _fmt(values) -> str:
    return "[" + ", ".join(f"{float(v):.6g}" for v in np.atleast_1d(values)) + "]"


def _attrs(**attributes) -> str:
    return " ".join(f"{key}={quoteattr(str(value))}" for key, value in attributes.items() if value is not None)


def _geom(shape: Shape, indent: str) -> str:
    attrs = {"name": shape.name, "type": shape.kind}
    if shape.kind == "plane":
        hx, hy = shape.size[0], shape.size[1]
        spacing = max(hx, hy) / 10 or 1.0  # the third size only spaces the drawn grid
        attrs["size"] = _vec((hx, hy, shape.size[2] if len(shape.size) == 3 else spacing))
    elif shape.kind == "mesh":
        attrs["mesh"] = shape.name
    elif shape.kind == "hfield":  # its asset, of the shape's name
        attrs["hfield"] = shape.name
    else:
        attrs["size"] = _vec(shape.size)
    pos = _hfield_as_mujoco(shape)[2] if shape.kind == "hfield" else shape.pos
    attrs.update(pos=_vec(pos), quat=_vec(shape.quat), contype="0", conaffinity="0")
    return f"{indent}<geom {_attrs(**attrs)}/>"


def _hfield_as_mujoco(shape: Shape) -> tuple[np.ndarray, tuple, np.ndarray]:
    """(elevation (nrow, ncol), size (4,), pos (3,)): a hfield shape as MuJoCo's compiler keeps it, which shifts its
    elevations to a least of 0 and scales them to a greatest of 1: the shape's least height moved into the geom's
    position along its z axis (its base with it), the range into size[2] (a flat field: elevations 0 at its
    height). MuJoCo holds elevations in single precision: its surface is within 6e-8 of size[2] of rbody's."""
    heights = np.asarray(shape.heights, dtype=float)
    sx, sy, sz, base = shape.size
    low, span = heights.min(), heights.max() - heights.min()
    elevation = (heights - low) / span if span > 1e-14 else np.zeros_like(heights)
    axis = quat_to_matrix(np.asarray(shape.quat))[:, 2]
    pos = np.asarray(shape.pos) + axis * (low * sz)
    return elevation, (sx, sy, sz * span if span > 1e-14 else sz, base + low * sz), pos


def _inertial(exported: ExportedInertia, indent: str) -> str:
    inertia = exported.inertia
    if exported.form == "full":
        t = inertia.tensor
        full = _vec((t[0, 0], t[1, 1], t[2, 2], t[0, 1], t[0, 2], t[1, 2]))
        return f"{indent}<inertial {_attrs(pos=_vec(inertia.com), mass=_num(inertia.mass), fullinertia=full)}/>"
    quat = quat_from_matrix(exported.axes)
    attrs = _attrs(pos=_vec(inertia.com), quat=_vec(quat), mass=_num(inertia.mass), diaginertia=_vec(exported.moments))
    return f"{indent}<inertial {attrs}/>"


def _fluid_box_inertial(exported: ExportedInertia, axes, indent: str) -> str:
    """A fluid box body's inertial in the principal form on its own axes (MuJoCo's inertia box takes its sides along
    them; from a full tensor its solver could pick others where two moments are equal), when the tensor is diagonal
    on them; otherwise the usual form."""
    rotation = quat_to_matrix(np.asarray(axes, dtype=np.float64))
    local = rotation.T @ exported.inertia.tensor @ rotation
    off = np.abs(local - np.diag(np.diag(local)))
    if exported.note or np.max(off) > 1e-12 * np.max(np.abs(local)):
        return _inertial(exported, indent)
    attrs = _attrs(pos=_vec(exported.inertia.com), quat=_vec(axes), mass=_num(exported.inertia.mass),
                   diaginertia=_vec(np.diag(local)))
    return f"{indent}<inertial {attrs}/>"


def _joint(joint: Joint, indent: str, limit: tuple[float, float] | None = None) -> str:
    extra = {name: _num(getattr(joint, name)) for name in _JOINT_ATTRIBUTES if getattr(joint, name, 0.0) != 0.0}
    if joint.actuatorgravcomp:
        extra["actuatorgravcomp"] = "true"
    if joint.actuatorfrcrange is not None:
        extra.update(actuatorfrclimited="true", actuatorfrcrange=_vec(joint.actuatorfrcrange))
    limit = joint.range if joint.range is not None else limit  # the joint's own, else a scene's declared one
    if limit is not None and joint.kind != "free":  # [rad | m]; a ball's (0, largest angle)
        extra.update(limited="true", range=_vec(limit))
    if joint.frictionloss > 0:
        extra.update(frictionloss=_num(joint.frictionloss))
    if joint.kind == "free":
        extra.pop("ref", None)
        if extra:  # <freejoint> takes no damping or armature; <joint type="free"> does
            return f"{indent}<joint {_attrs(name=joint.name, type='free', **extra)}/>"
        return f"{indent}<freejoint {_attrs(name=joint.name)}/>"
    if joint.kind == "ball":
        extra.pop("ref", None)
        return f"{indent}<joint {_attrs(name=joint.name, type='ball', pos=_vec(joint.anchor), **extra)}/>"
    attrs = _attrs(name=joint.name, type=_MJCF_JOINT[joint.kind], pos=_vec(joint.anchor), axis=_vec(joint.axis),
                   **extra)
    if joint.kind == "roll":  # the slide along l first, then the hinge (module docstring)
        slide_ref = {"ref": _num(joint.radius * joint.ref)} if joint.ref != 0.0 else {}
        slide = _attrs(name=joint.name + ROLL_SLIDE_SUFFIX, type="slide", pos=_vec(joint.anchor),
                       axis=_vec(joint.line), **slide_ref)
        return f"{indent}<joint {slide}/>\n{indent}<joint {attrs}/>"
    return f"{indent}<joint {attrs}/>"


def _roll_equality(joint: Joint, dt: float, indent: str) -> str:
    """The joint equality slide = a hinge of a roll joint, at MuJoCo's stiffest (module docstring)."""
    attrs = _attrs(name=joint.name + "_rolls", joint1=joint.name + ROLL_SLIDE_SUFFIX, joint2=joint.name,
                   polycoef=_vec((0.0, joint.radius, 0.0, 0.0, 0.0)),
                   solref=_vec((EQUALITY_TIMECONST_STEPS * dt, 1.0)), solimp=_vec(EQUALITY_SOLIMP))
    return f"{indent}<joint {attrs}/>"


def _equality_sites(equalities) -> dict[str, list[str]]:
    """body name (or world) -> the <site>s that the equalities join (site semantics: each exact, whatever the pose
    MuJoCo compiles the bodies in): a connect's two points; a weld's point on body1 turned by its relative
    orientation and its anchor on body2."""
    sites: dict[str, list[str]] = {}
    for e in equalities:
        if e.kind == "connect":
            pairs = ((e.body1, e.anchor, (1.0, 0.0, 0.0, 0.0)), (e.body2, e.anchor2, (1.0, 0.0, 0.0, 0.0)))
        elif e.kind == "weld":
            pairs = ((e.body1, e.relpose[:3], e.relpose[3:]), (e.body2, e.anchor, (1.0, 0.0, 0.0, 0.0)))
        else:
            continue
        for k, (body, pos, quat) in enumerate(pairs, start=1):
            sites.setdefault(body, []).append(
                f"<site {_attrs(name=f'{e.name}_site{k}', pos=_vec(pos), quat=_vec(_unit_quat(quat)))}/>")
    return sites


def _equality(e) -> str:
    active = {} if e.active else {"active": "false"}
    if e.kind == "joint":
        joint2 = {"joint2": e.joint2} if e.joint2 else {}
        return f"<joint {_attrs(name=e.name, joint1=e.joint1, **joint2, polycoef=_vec(e.polycoef), **active)}/>"
    if e.kind == "tendon":
        tendon2 = {"tendon2": e.tendon2} if e.tendon2 else {}
        return f"<tendon {_attrs(name=e.name, tendon1=e.tendon1, **tendon2, polycoef=_vec(e.polycoef), **active)}/>"
    return f"<{e.kind} {_attrs(name=e.name, site1=f'{e.name}_site1', site2=f'{e.name}_site2', **active)}/>"


def mesh_inertia_mode(path: str) -> str:
    """The inertia mode to_mjcf writes for a mesh asset: "exact" (MuJoCo's exact volume integrals: right for any
    closed mesh, should a user switch inertiafromgeom on) where MuJoCo's compiler accepts it, a mesh whose faces
    are consistently oriented and enclose a positive volume; else "legacy", which it always accepts (MuJoCo refuses
    "exact" for an open or inside-out mesh: "inconsistent orientation", "mesh volume is negative"). The body's mass
    properties are the explicit <inertial> either way."""
    try:
        import trimesh

        mesh = trimesh.load(path, force="mesh", process=False)
        if mesh.is_winding_consistent and mesh.is_watertight and float(mesh.volume) > 1e-15:
            return "exact"
    except Exception:  # a file trimesh cannot read: MuJoCo reads it by its own rules
        pass
    return "legacy"


def _spring_lengths(scene) -> dict[str, tuple[float, float]]:
    """Each tendon's spring dead band as the engine resolved it (rbody.engine.system.Multibody), so that MuJoCo reads
    the same lengths whatever pose it would compute them at."""
    from rbody.engine.elements import T_HIGH, T_LOW, TEN_SIZE, X_TEN

    model = getattr(scene, "multibody", None)
    if model is None or not getattr(model, "ntendon", 0):
        return {}
    row, start = model.params, model.arrays.row.size
    out = {}
    for t, name in enumerate(model.tendon_names):
        r = int(row[start + X_TEN]) + t * TEN_SIZE
        out[name] = (float(row[r + T_LOW]), float(row[r + T_HIGH]))
    return out


def _comment(text: str) -> str:
    return text.replace("--", "- -")


def to_mjcf(scene: Scene, *, dt: float | None = None, min_inertia: float | None = None,
            integrator: str | None = None, solref: Sequence[float] | None = None,
            solimp: Sequence[float] | None = None, condim: int | None = None, cone: str | None = None,
            impratio: float | None = None, noslip_iterations: int | None = None) -> str:
    """The MJCF document (str) of an unbatched `scene`, which mujoco.MjModel.from_xml_string compiles.

    dt:          time step [s] (default MuJoCo's 0.002); also sets the impact stiffness K = (1/dt)^2
    min_inertia: floor for every principal moment [kg m^2] (else zero moments take their shapes' thickness)
    integrator:  "Euler", "RK4", "implicit" or "implicitfast" (default Euler with impacts, else RK4)
    solref, solimp, condim: override every contact pair's value (see contact_parameters)
    cone:        "pyramidal" or "elliptic" (default elliptic when some contact has friction)
    impratio:    frictional-to-normal impedance ratio (default 100 when some contact has friction)
    noslip_iterations: MuJoCo's no-slip post-processing iterations (default none)
    Raises ValueError for what MuJoCo would refuse (module docstring) and for a batched scene.
    """
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene")
    if scene.batch_shape:
        raise ValueError(f"scene {scene.name!r} is a batch of shape {scene.batch_shape}: an MJCF model holds one "
                         "scene; use scene.item(i)")
    if dt is None:  # a scene read from MJCF keeps its model's step and integrator
        dt = getattr(scene, "timestep", None) or DEFAULT_TIMESTEP
        integrator = integrator or getattr(scene, "integrator", None)
    dt = positive(dt, "dt")
    if not 1e-150 < dt < 1e150:  # K = (1/dt)^2 and (pi / (30 dt))^2 must be finite and > 0
        raise ValueError(f"dt={dt!r} s: outside 1e-150..1e150, where the contact stiffness (1/dt)^2 would "
                         "overflow or vanish")
    if integrator is not None:
        one_of(integrator, "integrator", INTEGRATORS)
    if cone is not None:
        one_of(cone, "cone", CONES)
    if impratio is not None:
        positive(impratio, "impratio")
    if noslip_iterations is not None and (not isinstance(noslip_iterations, (int, np.integer))
                                          or isinstance(noslip_iterations, bool) or noslip_iterations < 0):
        raise ValueError(f"noslip_iterations={noslip_iterations!r}: expected a whole number >= 0")
    if condim is not None:
        one_of(condim, "condim", CONDIMS)
    if solref is not None:
        solref = tuple(finite_array(solref, "solref", shape=(2,)).tolist())
    if solimp is not None:
        solimp = tuple(finite_array(solimp, "solimp", ndim=1).tolist())
        if len(solimp) not in (3, 5):
            raise ValueError(f"solimp={solimp!r}: expected 3 or 5 numbers (dmin, dmax, width[, midpoint, power])")

    layout = scene.layout
    _check_layout(layout)
    exported = {body.name: exported_inertia(body, min_inertia=min_inertia) for body in layout.bodies}
    impacts = has_impacts(layout)
    frictional = any(c.friction > 0 for c in layout.contacts)
    integrator = integrator or ("Euler" if impacts else "RK4")
    if frictional:
        cone = cone or "elliptic"
        impratio = FRICTION_IMPRATIO if impratio is None else impratio
    gravity = scene.gravity if scene.applies_gravity else 0.0
    pairs = [(c, contact_parameters(c, dt, solref=solref, solimp=solimp, condim=condim)) for c in layout.contacts]
    qpos, qvel = initial_state(layout)
    order = body_order(layout)
    limits = dict(getattr(scene, "limits", None) or {})  # MJCFScene: the model's declared joint ranges
    table = getattr(scene, "constraint_table", None)  # a TreeScene's equalities, made explicit by the engine
    equalities = table.equalities if table is not None else tuple(e for e in layout.equalities if e.kind == "joint")
    sites = _equality_sites(equalities)
    restitutions = [(j.name, j.restitution) for j in layout.joints if j.range is not None and j.restitution > 0]
    restitutions += [(t.name, t.restitution) for t in layout.tendons if t.range is not None and t.restitution > 0]

    # --- the comment: what the model holds and where it came from ---
    counts = {kind: sum(j.kind == kind for j in layout.joints) for kind in ("hinge", "slide", "ball", "free", "roll")}
    rolls = [j for j in layout.joints if j.kind == "roll"]
    lines = [
        f"Generated by rbody (rbody.mjcf.to_mjcf) from scene {scene.describe()}.",
        f"Contains bodies {', '.join(b.name for b in order)}; joints: "
        + ", ".join(f"{n} {k}" for k, n in counts.items() if n) + f"; {len(layout.fixed)} world geoms, "
        f"{sum(len(b.shapes) for b in order)} body geoms; {len(pairs)} contact pairs.",
        "Only what the scene uses: every geom has contype=conaffinity=0, so nothing collides except the",
        "<pair>s below. Mass properties are explicit (inertiafromgeom=false): rbody's mass, centre of mass",
        "and tensor about it, body frame; joints have no damping, armature, friction, springs or limits."
        if not limits and not any(getattr(j, key, 0.0) for j in layout.joints for key in _JOINT_ATTRIBUTES) else
        "and tensor about it, body frame; joints have no friction, and limits, damping, stiffness, springref, "
        "armature and ref only where the scene gives them.",
        (f"gravity {gravity!r} m/s^2 along -z" if gravity == scene.gravity else
         f"gravity 0 (the scene applies no uniform gravity, though it states g = {scene.gravity!r} m/s^2)")
        + f"; timestep {dt!r} s; integrator {integrator}.",
        f"Initial state: keyframe {INITIAL_KEY!r} (free joints: angular velocity in the body frame).",
    ]
    if (any(j.range is not None or j.frictionloss > 0 for j in layout.joints) or equalities
            or any(t.range is not None or t.frictionloss > 0 for t in layout.tendons)):
        lines.append("Joint limits, frictionloss and equalities as the scene gives them, at MuJoCo's default softness "
                     "(rbody holds them rigidly); connect and weld with sites at the points rbody joins; a limit's "
                     "restitution as the custom numeric rbody.restitution.<joint> (MuJoCo ignores it); tendons' "
                     "limits and frictionloss likewise (rbody.restitution.<tendon>).")
    if impacts:
        lines.append(f"Impacts (restitution > 0): contact springs solref=(-K, -B), solimp={CONTACT_SOLIMP}; elastic "
                     f"(e = 1): K=(1/dt)^2={1 / dt**2!r}, B=0; 0 < e < 1: K=(pi/({IMPACT_STEPS} dt))^2 with the "
                     "damping of restitution e; condim 1 where frictionless.")
    if rolls:
        lines.append(f"Roll joints ({', '.join(j.name for j in rolls)}): each is a slide <name>{ROLL_SLIDE_SUFFIX} "
                     "along axis x normal, then a hinge <name> about its axis, tied by a joint equality slide = a hinge "
                     f"(rolling without slipping, a the rolling radius), solref=({EQUALITY_TIMECONST_STEPS:g} dt, 1)="
                     f"({EQUALITY_TIMECONST_STEPS * dt!r}, 1), solimp={EQUALITY_SOLIMP}: a soft constraint MuJoCo "
                     "solves every step, so the constraint solver stays on. rbody integrates the one coordinate q "
                     "(the hinge); the slide is a q0 at the start.")
    for name, item in exported.items():
        if item.note:
            lines.append(f"Body {name!r}: {item.note}.")
        elif item.form == "principal":
            lines.append(f"Body {name!r}: on A + B = C, written as principal moments and axes (quat + diaginertia).")
    comment = "\n     ".join(part for line in lines for part in textwrap.wrap(_comment(line), 100))

    # --- the document ---
    out = [f"<mujoco {_attrs(model=scene.name)}>", f"  <!-- {comment} -->",
           '  <compiler angle="radian" inertiafromgeom="false" alignfree="false" autolimits="true"/>']
    option = {"timestep": _num(dt), "gravity": _vec((0.0, 0.0, -gravity)), "integrator": integrator,
              "cone": cone, "impratio": None if impratio is None else _num(impratio),
              "noslip_iterations": None if noslip_iterations is None else str(int(noslip_iterations)),
              "actuatorgroupdisable": (str(mjcf_actuators.DISABLED_GROUP)
                                       if any(a.disabled for a in layout.actuators) else None)}
    if layout.fluid is not None:  # MuJoCo's fluid forces: the option, each box body's axes, each ellipsoid
        option.update(density=_num(layout.fluid.density), viscosity=_num(layout.fluid.viscosity),
                      wind=_vec(layout.fluid.wind))
    box_axes = {box.body: box.axes for box in layout.fluid.boxes} if layout.fluid is not None else {}
    ellipsoids = list(layout.fluid.ellipsoids) if layout.fluid is not None else []
    out.append(f"  <option {_attrs(**option)}/>")
    if restitutions:
        out.append("  <custom>")
        out.extend(f"    <numeric {_attrs(name=f'rbody.restitution.{name}', data=_num(e))}/>" for name, e in restitutions)
        out.append("  </custom>")
    meshes = [s for s in list(layout.fixed) + [s for b in order for s in b.shapes] if s.kind in ("mesh", "hfield")]
    if meshes:
        out.append("  <asset>")
        for shape in meshes:
            if shape.kind == "hfield":
                elevation, size, _pos = _hfield_as_mujoco(shape)
                # elevation lists the rows from y = +size[1] down (MuJoCo's compiler reverses them): the shape's
                # row 0, at y = -size[1], last
                attrs = _attrs(name=shape.name, nrow=elevation.shape[0], ncol=elevation.shape[1], size=_vec(size),
                               elevation=_vec(elevation[::-1].ravel()))
                out.append(f"    <hfield {attrs}/>")
                continue
            if shape.vertices:  # the points whose convex hull collides, as MuJoCo collides a mesh: written out
                out.append(f"    <mesh {_attrs(name=shape.name, vertex=_vec(np.ravel(shape.vertices)))}/>")
                continue
            # an absolute path: the model compiles from any folder (the mesh file stays where it is)
            mode = mesh_inertia_mode(shape.mesh)
            out.append(f"    <mesh {_attrs(name=shape.name, file=os.path.abspath(shape.mesh), inertia=mode)}/>")
        out.append("  </asset>")
    out.append("  <worldbody>")
    for shape in layout.fixed:
        out.append(_geom(shape, "    "))
    out.extend("    " + site for site in sites.get(WORLD, ()))
    for name, point, quat in mjcf_actuators.tendon_sites(layout.tendons, WORLD, layout.actuators):
        out.append(f"    <site {_attrs(name=name, pos=_vec(point), quat=_vec(quat))}/>")
    children: dict[str, list[Body]] = {}
    for body in layout.bodies:
        children.setdefault(body.parent, []).append(body)

    def write(body: Body, indent: str) -> None:
        quat = _unit_quat(body.quat)
        gravcomp = _num(body.gravcomp) if body.gravcomp else None
        out.append(f"{indent}<body {_attrs(name=body.name, pos=_vec(body.pos), quat=_vec(quat), gravcomp=gravcomp)}>")
        for joint in layout.joints:
            if joint.body == body.name:
                out.append(_joint(joint, indent + "  ", limits.get(joint.name)))
        out.append(_fluid_box_inertial(exported[body.name], box_axes[body.name], indent + "  ")
                   if body.name in box_axes else _inertial(exported[body.name], indent + "  "))
        for shape in body.shapes:
            out.append(_geom(shape, indent + "  "))
        out.extend(indent + "  " + site for site in sites.get(body.name, ()))
        for k, shape in enumerate(e for e in ellipsoids if e.body == body.name):
            attrs = _attrs(name=f"{body.name}_fluid{k}", type="ellipsoid", size=_vec(shape.semiaxes),
                           pos=_vec(shape.pos), quat=_vec(shape.quat), contype="0", conaffinity="0",
                           fluidshape="ellipsoid", fluidcoef=_vec(shape.coefficients))
            out.append(f"{indent}  <geom {attrs}/>")
        for name, point, quat in mjcf_actuators.tendon_sites(layout.tendons, body.name, layout.actuators):
            out.append(f"{indent}  <site {_attrs(name=name, pos=_vec(point), quat=_vec(quat))}/>")
        for child in children.get(body.name, ()):
            write(child, indent + "  ")
        out.append(f"{indent}</body>")

    for body in children.get(WORLD, ()):
        write(body, "    ")
    out.append("  </worldbody>")
    if pairs:
        out.append("  <contact>")
        for contact, p in pairs:
            margin = {"margin": _num(contact.margin)} if contact.margin else {}
            out.append("    <pair " + _attrs(geom1=contact.shape_a, geom2=contact.shape_b, condim=str(p["condim"]),
                                             friction=_vec(p["friction"]), solref=_vec(p["solref"]),
                                             solimp=_vec(p["solimp"]), **margin) + "/>")
        out.append("  </contact>")
    if layout.tendons:
        springs = _spring_lengths(scene)
        out.append("  <tendon>")
        for tendon in layout.tendons:
            out.extend(mjcf_actuators.tendon_xml(tendon, springs.get(tendon.name), _attrs, _vec, _num, "    "))
        out.append("  </tendon>")
    if layout.actuators:
        out.append("  <actuator>")
        out.extend(mjcf_actuators.actuator_xml(a, _attrs, _vec, _num, "    ") for a in layout.actuators)
        out.append("  </actuator>")
    if rolls or equalities:
        out.append("  <equality>")
        out.extend(_roll_equality(joint, dt, "    ") for joint in joint_order(layout) if joint.kind == "roll")
        out.extend("    " + _equality(e) for e in equalities)
        out.append("  </equality>")
    if qpos.size or layout.actuators:
        controls = {}
        if layout.actuators and hasattr(scene, "_controls0"):  # a TreeScene's first batch element's act0, ctrl0
            act0, ctrl0 = scene._controls0()
            controls = {"ctrl": _vec(ctrl0[0])} | ({"act": _vec(act0[0])} if act0.shape[1] else {})
        out.append("  <keyframe>")
        out.append(f"    <key {_attrs(name=INITIAL_KEY, qpos=_vec(qpos), qvel=_vec(qvel), **controls)}/>")
        out.append("  </keyframe>")
    out.append("</mujoco>")
    return "\n".join(out) + "\n"


__all__ = ["to_mjcf", "exported_inertia", "ExportedInertia", "contact_parameters", "initial_state",
           "body_order", "joint_order", "has_impacts", "shape_inertia", "DEFAULT_TIMESTEP",
           "EQUALITY_SOLIMP", "ROLL_SLIDE_SUFFIX"]
