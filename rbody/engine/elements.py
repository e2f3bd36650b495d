"""Force elements: the section of a tree's params row after its joints, holding tendons, actuators and controls.

A tree's params row (rbody.engine.multibody) ends with its degree-of-freedom records; the force elements follow
at E = H_DOF offset + nv * DOF_SIZE, so that every algorithm of the tree reads the same row unchanged and a tree
without force elements is the same numbers as before. Offsets in the section are absolute, as in the tree's.

    header (X_HEADER floats at E):
      X_NU      actuators (and controls; MuJoCo's nu)
      X_NA      activations (actuators whose dynamics is not "none"; MuJoCo's na)
      X_NTEN    tendons
      X_ACT     offset of the actuator records (ACT_SIZE each)
      X_TEN     offset of the tendon records (TEN_SIZE each)
      X_CTRL    offset of the controls u (nu): the control held through the current step
      X_STEP    the time step h [s] of the run (actearly and MuJoCo's exact filter read it)
      X_SCHED   offset of a control schedule (rows of nu, one per step), -1 without one (rbody.control)
      X_NSCHED  rows of the schedule
      X_GRAVCOMP offset of the bodies' gravity compensation (nb), -1 without any (rbody.engine.passive)
      X_FLUID   offset of the fluid section, -1 without fluid forces (rbody.engine.fluid)
      X_ACTGC   offset of a flag per degree of freedom (nv): 1 where gravity compensation is an actuator force
      X_JNTLIM  offset of the joints' actuator force clamps (nj records: limited, low, high)
      X_BLOCK   offset of a constraint block after the section (rbody.engine.constraints.table), -1 without one:
                a constrained tree's row always holds this section, empty where the tree has no force element
      X_ACTIVE  1 where the section holds any force element (the constraint layer then adds their forces), else 0
    actuator record (ACT_SIZE): transmission (0 joint, 1 tendon), target (joint or tendon index), the target
      joint's kind code (-1 for a tendon), its qpos and qvel addresses, dynamics, gain and bias codes, dynprm,
      gainprm (3), biasprm (3), gear (6), ctrl limited and range (2), force limited and range (2), act limited
      and range (2), actearly, the activation's index in act (-1 none), disabled, a site's pos (3) and quat (4)
    tendon record (TEN_SIZE): kind (0 fixed, 1 spatial), entries, offset of the entries, stiffness, damping,
      spring length low and high
    tendon entries (PATH_SIZE each): fixed (qpos address, qvel address, coef, 0); spatial (body index, -1 for the
      world; point (3) in the body frame [m])

The native state of a tree with activations is y = (qpos (nq), qvel (nv), phi (3 nrot), act (na)), and a run with
a control schedule appends one more entry, the number of steps taken (rbody.control).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from rbody.engine.multibody import DOF_SIZE, H_DOF, H_DOFS, KIND_CODE, TreeArrays
from rbody.engine.schema import FLOAT, INT, Record
from rbody.layout import ACTUATOR_BIASES, ACTUATOR_DYNAMICS, ACTUATOR_GAINS, JOINTS, WORLD, Layout

# The section's header and records, declared once (rbody.engine.schema; docs/design.md prints them).
ELEMENTS_HEADER = Record("force-element header", [
    ("nu", 1, INT, "actuators (and controls; MuJoCo's nu)"),
    ("na", 1, INT, "activations (MuJoCo's na)"),
    ("ntendon", 1, INT, "tendons"),
    ("actuators", 1, INT, "where the actuator records start"),
    ("tendons", 1, INT, "where the tendon records start"),
    ("ctrl", 1, INT, "where the controls u (nu) held through the current step start"),
    ("step", 1, FLOAT, "the run's time step h [s] (actearly, the exact filter)"),
    ("schedule", 1, INT, "where a control schedule starts (rows of nu, one per step), -1 without one"),
    ("nschedule", 1, INT, "rows of the schedule"),
    ("gravcomp", 1, INT, "where the bodies' gravity compensation (nb) starts, -1 without any"),
    ("fluid", 1, INT, "where the fluid section starts, -1 without fluid forces"),
    ("actgravcomp", 1, INT, "where a flag per dof (nv) starts: 1 where gravity compensation is an actuator force"),
    ("jointlimits", 1, INT, "where the joints' actuator force clamps (nj records: limited, low, high) start"),
    ("block", 1, INT, "where a constraint block after the section starts, -1 without one"),
    ("active", 1, INT, "1 where the section holds any force element, else 0"),
    ("reserved", 1, FLOAT, "unused (0)"),
])
(X_NU, X_NA, X_NTEN, X_ACT, X_TEN, X_CTRL, X_STEP, X_SCHED, X_NSCHED, X_GRAVCOMP, X_FLUID, X_ACTGC, X_JNTLIM, X_BLOCK,
 X_ACTIVE) = ELEMENTS_HEADER.offsets()[:15]
X_HEADER = ELEMENTS_HEADER.size

ACTUATOR = Record("actuator", [
    ("transmission", 1, INT, "0 joint, 1 tendon, 2 site"),
    ("target", 1, INT, "joint or tendon index (a site's body)"),
    ("joint_kind", 1, INT, "the target joint's kind code (-1 for a tendon)"),
    ("qadr", 1, INT, "its qpos address"),
    ("dadr", 1, INT, "its qvel address"),
    ("dynamics", 1, INT, "none, integrator, filter, filterexact"),
    ("gain", 1, INT, "fixed, affine"),
    ("bias", 1, INT, "none, affine"),
    ("dynprm", 1, FLOAT, "the filter's time constant [s]"),
    ("gainprm", 3, FLOAT, "gain parameters"),
    ("biasprm", 3, FLOAT, "bias parameters"),
    ("gear", 6, FLOAT, "gear (a site's wrench: 6)"),
    ("ctrllimited", 1, INT, "controls clamped"),
    ("ctrlrange", 2, FLOAT, "their range"),
    ("forcelimited", 1, INT, "force clamped"),
    ("forcerange", 2, FLOAT, "its range [N | N m]"),
    ("actlimited", 1, INT, "activation clamped"),
    ("actrange", 2, FLOAT, "its range"),
    ("actearly", 1, INT, "force from the next activation"),
    ("actadr", 1, INT, "its activation's index in act (-1: none)"),
    ("disabled", 1, INT, "1: in a disabled actuator group"),
    ("sitepos", 3, FLOAT, "a site transmission's position in its body [m]"),
    ("sitequat", 4, FLOAT, "its orientation"),
])
(A_TRN, A_ID, A_JKIND, A_QADR, A_DADR, A_DYN, A_GAIN, A_BIAS, A_DYNPRM, A_GAINPRM, A_BIASPRM, A_GEAR, A_CTRLLIM,
 A_CTRLRANGE, A_FORCELIM, A_FORCERANGE, A_ACTLIM, A_ACTRANGE, A_ACTEARLY, A_ACTADR, A_DISABLED, A_SITEPOS,
 A_SITEQUAT) = ACTUATOR.offsets()
ACT_SIZE = ACTUATOR.size

FLUID_HEADER = 9   # nbox, nell, density, viscosity, wind (3), box and ellipsoid offsets (rbody.engine.fluid)
BOX_SIZE = 8       # body, axes (4), sides (3)
ELL_SIZE = 22      # body, pos (3), quat (4), semiaxes (3), virtual mass (3), virtual inertia (3), coefficients (5)

TENDON = Record("tendon", [
    ("kind", 1, INT, "0 fixed, 1 spatial"),
    ("entries", 1, INT, "path entries"),
    ("path", 1, INT, "where its entries start"),
    ("stiffness", 1, FLOAT, "[N/m]"),
    ("damping", 1, FLOAT, "[N s/m]"),
    ("springlow", 1, FLOAT, "spring length, low end [m]"),
    ("springhigh", 1, FLOAT, "high end [m]"),
])
T_KIND, T_N, T_PATH, T_STIFF, T_DAMP, T_LOW, T_HIGH = TENDON.offsets()
TEN_SIZE = TENDON.size
PATH_ENTRY = Record("tendon path entry", [
    ("first", 1, FLOAT, "fixed: qpos address; spatial: body index (-1: the world)"),
    ("second", 1, FLOAT, "fixed: qvel address; spatial: point x [m]"),
    ("third", 1, FLOAT, "fixed: coefficient; spatial: point y [m]"),
    ("fourth", 1, FLOAT, "fixed: 0; spatial: point z [m]"),
])
PATH_SIZE = PATH_ENTRY.size

TRN_JOINT, TRN_TENDON, TRN_SITE = 0, 1, 2
TEN_FIXED, TEN_SPATIAL = 0, 1
DYN_NONE, DYN_INTEGRATOR, DYN_FILTER, DYN_FILTEREXACT = (ACTUATOR_DYNAMICS.index(k) for k in ACTUATOR_DYNAMICS)
GAIN_FIXED, GAIN_AFFINE = (ACTUATOR_GAINS.index(k) for k in ACTUATOR_GAINS)
BIAS_NONE, BIAS_AFFINE = (ACTUATOR_BIASES.index(k) for k in ACTUATOR_BIASES)
MJ_MINVAL = 1e-15  # MuJoCo's mjMINVAL: a filter's time constant below it is taken as it


@njit(cache=True, inline="always")
def extension_start(p) -> int:
    """E: where the force elements start in the params row p (the end of the tree's records)."""
    return int(p[H_DOF]) + int(p[H_DOFS]) * DOF_SIZE


@njit(cache=True, inline="always")
def block_offset(p) -> int:
    """Where the constraint block starts in a params row: after the tree's row and its force-element section
    (present, empty or not, in every constrained row), whose X_BLOCK records the offset."""
    return int(p[extension_start(p) + X_BLOCK])


@dataclass(frozen=True)
class ElementArrays:
    """The force elements of a tree in numpy: the section's row and the names that index it.

    row: (X_HEADER + ...) the section, offsets absolute from `start` (the tree row's length)
    actuator_names, tendon_names: MuJoCo's order; act_actuators: the actuator of each activation
    spring_pending: tendons whose spring length is to be set from their length at the reference pose
    """

    row: np.ndarray
    start: int
    nu: int
    na: int
    actuator_names: tuple[str, ...]
    tendon_names: tuple[str, ...]
    act_actuators: tuple[int, ...]
    spring_pending: tuple[int, ...]


def has_elements(layout: Layout) -> bool:
    """Whether the layout holds anything of this section (else the tree's row is the whole model)."""
    return bool(layout.actuators or layout.tendons or any(b.gravcomp for b in layout.bodies)
                or any(j.actuatorfrcrange is not None for j in layout.joints) or has_fluid(layout))


def has_fluid(layout: Layout) -> bool:
    """Whether the layout's fluid applies a force (MuJoCo: density or viscosity > 0, and something in it)."""
    fluid = layout.fluid
    return bool(fluid is not None and (fluid.density > 0 or fluid.viscosity > 0) and (fluid.boxes or fluid.ellipsoids))


def build_elements(layout: Layout, arrays: TreeArrays, start: int) -> ElementArrays:
    """The force-element section of `layout` for the tree `arrays` whose row has `start` floats; ValueError, naming
    the element, for a reference to no joint, tendon or body, a fixed tendon on a ball or free joint, a gear that
    does not fit its joint, or two elements of one name."""
    joints = {name: j for j, name in enumerate(arrays.joint_names)}
    bodies = {name: i for i, name in enumerate(arrays.names)}
    tendons = {}
    for t, tendon in enumerate(layout.tendons):
        if tendon.name in tendons:
            raise ValueError(f"two tendons are called {tendon.name!r}: tendon names must be unique")
        tendons[tendon.name] = t
    names = set()
    for actuator in layout.actuators:
        if actuator.name in names:
            raise ValueError(f"two actuators are called {actuator.name!r}: actuator names must be unique")
        names.add(actuator.name)

    nu, ntendon = len(layout.actuators), len(layout.tendons)
    entries = sum(max(len(t.joints), len(t.sites)) for t in layout.tendons)
    act_at = start + X_HEADER
    ten_at = act_at + nu * ACT_SIZE
    path_at = ten_at + ntendon * TEN_SIZE
    ctrl_at = path_at + entries * PATH_SIZE
    nb, nj, nv = len(arrays.names), len(arrays.joint_names), arrays.nv
    gravcomp_at = ctrl_at + nu
    actgc_at = gravcomp_at + nb
    jntlim_at = actgc_at + nv
    fluid_at = jntlim_at + 3 * nj
    fluid = fluid_row(layout, arrays, fluid_at) if has_fluid(layout) else np.zeros(0)
    size = fluid_at + fluid.size - start
    row = np.zeros(size)
    if fluid.size:
        row[fluid_at - start:] = fluid
        row[X_FLUID] = fluid_at
    row[X_NU], row[X_NTEN], row[X_ACT], row[X_TEN], row[X_CTRL] = nu, ntendon, act_at, ten_at, ctrl_at
    row[X_STEP], row[X_SCHED] = 0.002, -1
    row[X_FLUID] = fluid_at if fluid.size else -1
    row[X_GRAVCOMP], row[X_ACTGC], row[X_JNTLIM] = gravcomp_at, actgc_at, jntlim_at
    row[X_BLOCK], row[X_ACTIVE] = -1, float(has_elements(layout))
    by_name = {body.name: body for body in layout.bodies}
    for i, name in enumerate(arrays.names):
        row[gravcomp_at - start + i] = float(by_name[name].gravcomp)
    joint_of = {joint.name: joint for joint in layout.joints}
    for j, name in enumerate(arrays.joint_names):
        joint = joint_of[name]
        if joint.actuatorgravcomp:
            first = int(arrays.dofadr[j])
            row[actgc_at - start + first:actgc_at - start + first + JOINTS[joint.kind].nv] = 1.0
        if joint.actuatorfrcrange is not None:
            row[jntlim_at - start + 3 * j:jntlim_at - start + 3 * j + 3] = (1.0,) + joint.actuatorfrcrange

    pending = []
    at = path_at
    for t, tendon in enumerate(layout.tendons):
        r = ten_at + t * TEN_SIZE - start
        what = f"tendon {tendon.name!r}"
        row[r + T_KIND] = TEN_FIXED if tendon.kind == "fixed" else TEN_SPATIAL
        row[r + T_N] = len(tendon.joints) if tendon.kind == "fixed" else len(tendon.sites)
        row[r + T_PATH] = at
        row[r + T_STIFF], row[r + T_DAMP] = tendon.stiffness, tendon.damping
        if tendon.springlength is None:
            pending.append(t)
        else:
            row[r + T_LOW], row[r + T_HIGH] = tendon.springlength
        if tendon.kind == "fixed":
            for name, coef in tendon.joints:
                if name not in joints:
                    raise ValueError(f"{what}: joint {name!r} is not a joint of the layout")
                j = joints[name]
                if not JOINTS[arrays.joint_kinds[j]].scalar:
                    raise ValueError(f"{what}: joint {name!r} is a {arrays.joint_kinds[j]} joint: a fixed tendon "
                                     "sums hinge and slide (and roll) coordinates only (MuJoCo's rule)")
                e = at - start
                row[e:e + 3] = arrays.qposadr[j], arrays.dofadr[j], coef
                at += PATH_SIZE
        else:
            for body, point in tendon.sites:
                if body != WORLD and body not in bodies:
                    raise ValueError(f"{what}: site on body {body!r}, which is neither {WORLD!r} nor a body of the "
                                     "layout")
                e = at - start
                row[e] = -1 if body == WORLD else bodies[body]
                row[e + 1:e + 4] = point
                at += PATH_SIZE

    na = 0
    act_actuators = []
    for i, actuator in enumerate(layout.actuators):
        r = act_at + i * ACT_SIZE - start
        what = f"actuator {actuator.name!r}"
        if actuator.transmission == "joint":
            if actuator.target not in joints:
                raise ValueError(f"{what}: target={actuator.target!r} is not a joint of the layout")
            j = joints[actuator.target]
            kind = arrays.joint_kinds[j]
            gear = np.asarray(actuator.gear)
            used = {"ball": 3, "free": 6}.get(kind, 1)
            if np.any(gear[used:] != 0):
                raise ValueError(f"{what}: gear={actuator.gear!r} on {kind} joint {actuator.target!r}, which takes "
                                 f"{used} gear component(s) (MuJoCo reads no more)")
            row[r + A_TRN], row[r + A_ID], row[r + A_JKIND] = TRN_JOINT, j, KIND_CODE[kind]
            row[r + A_QADR], row[r + A_DADR] = arrays.qposadr[j], arrays.dofadr[j]
        elif actuator.transmission == "site":
            if actuator.target not in bodies:
                raise ValueError(f"{what}: target={actuator.target!r} is not a body of the layout (a site transmission "
                                 "names the body that carries the site)")
            row[r + A_TRN], row[r + A_ID], row[r + A_JKIND] = TRN_SITE, bodies[actuator.target], -1
            row[r + A_QADR], row[r + A_DADR] = -1, -1
            row[r + A_SITEPOS:r + A_SITEPOS + 3] = actuator.site[0]
            row[r + A_SITEQUAT:r + A_SITEQUAT + 4] = actuator.site[1]
        else:
            if actuator.target not in tendons:
                raise ValueError(f"{what}: target={actuator.target!r} is not a tendon of the layout")
            if np.any(np.asarray(actuator.gear)[1:] != 0):
                raise ValueError(f"{what}: gear={actuator.gear!r}: a tendon transmission takes one gear component")
            row[r + A_TRN], row[r + A_ID], row[r + A_JKIND] = TRN_TENDON, tendons[actuator.target], -1
            row[r + A_QADR], row[r + A_DADR] = -1, -1
        row[r + A_DYN] = ACTUATOR_DYNAMICS.index(actuator.dynamics)
        row[r + A_GAIN] = ACTUATOR_GAINS.index(actuator.gain)
        row[r + A_BIAS] = ACTUATOR_BIASES.index(actuator.bias)
        row[r + A_DYNPRM] = actuator.dynprm
        row[r + A_GAINPRM:r + A_GAINPRM + 3] = actuator.gainprm
        row[r + A_BIASPRM:r + A_BIASPRM + 3] = actuator.biasprm
        row[r + A_GEAR:r + A_GEAR + 6] = actuator.gear
        for flag, at_range, value in ((A_CTRLLIM, A_CTRLRANGE, actuator.ctrlrange),
                                      (A_FORCELIM, A_FORCERANGE, actuator.forcerange),
                                      (A_ACTLIM, A_ACTRANGE, actuator.actrange)):
            if value is not None:
                row[r + flag] = 1.0
                row[r + at_range:r + at_range + 2] = value
        row[r + A_ACTEARLY] = float(actuator.actearly)
        row[r + A_DISABLED] = float(actuator.disabled)
        if actuator.stateful:
            row[r + A_ACTADR] = na
            act_actuators.append(i)
            na += 1
        else:
            row[r + A_ACTADR] = -1
    row[X_NA] = na
    ELEMENTS_HEADER.check(row, 0, 1)
    ACTUATOR.check(row, act_at - start, nu)
    TENDON.check(row, ten_at - start, ntendon)
    return ElementArrays(row=row, start=start, nu=nu, na=na,
                         actuator_names=tuple(a.name for a in layout.actuators),
                         tendon_names=tuple(t.name for t in layout.tendons), act_actuators=tuple(act_actuators),
                         spring_pending=tuple(pending))


def fluid_row(layout: Layout, arrays: TreeArrays, at: int) -> np.ndarray:
    """The fluid section (rbody.engine.fluid) of `layout` starting at offset `at` of the row: each box with its sides
    sqrt(6 (I_{k+1} + I_{k+2} - I_k) / m) from the principal moments I_k = e_k . I e_k along its axes e_k (MuJoCo's
    mj_inertiaBoxFluidModel), each ellipsoid's frame, semiaxes, added-mass factors and coefficients."""
    from rbody.motion import quat_to_matrix

    fluid = layout.fluid
    bodies = {name: i for i, name in enumerate(arrays.names)}
    by_name = {body.name: body for body in layout.bodies}
    for record in tuple(fluid.boxes) + tuple(fluid.ellipsoids):
        if record.body not in bodies:
            raise ValueError(f"fluid: body {record.body!r} is not a body of the layout")
    nbox, nell = len(fluid.boxes), len(fluid.ellipsoids)
    row = np.zeros(FLUID_HEADER + nbox * BOX_SIZE + nell * ELL_SIZE)
    row[0:4] = nbox, nell, fluid.density, fluid.viscosity
    row[4:7] = fluid.wind
    row[7], row[8] = at + FLUID_HEADER, at + FLUID_HEADER + nbox * BOX_SIZE
    for k, box in enumerate(fluid.boxes):
        r = FLUID_HEADER + k * BOX_SIZE
        body = by_name[box.body]
        axes = np.asarray(box.axes, dtype=np.float64) / np.linalg.norm(box.axes)
        rotation = quat_to_matrix(axes)
        moments = np.einsum("ak,ab,bk->k", rotation, np.asarray(body.inertia.tensor), rotation)
        mass = body.inertia.mass
        sides = [np.sqrt(max(MJ_MINVAL, moments[(k + 1) % 3] + moments[(k + 2) % 3] - moments[k]) / mass * 6.0)
                 if mass > 0 else 0.0 for k in range(3)]
        row[r] = bodies[box.body]
        row[r + 1:r + 5] = axes
        row[r + 5:r + 8] = sides
    for k, shape in enumerate(fluid.ellipsoids):
        r = FLUID_HEADER + nbox * BOX_SIZE + k * ELL_SIZE
        row[r] = bodies[shape.body]
        row[r + 1:r + 4] = shape.pos
        row[r + 4:r + 8] = np.asarray(shape.quat) / np.linalg.norm(shape.quat)
        row[r + 8:r + 11] = shape.semiaxes
        row[r + 11:r + 14] = shape.virtual_mass
        row[r + 14:r + 17] = shape.virtual_inertia
        row[r + 17:r + 22] = shape.coefficients
    return row


__all__ = ["ElementArrays", "fluid_row", "has_fluid", "build_elements", "has_elements", "extension_start",
           "block_offset", "X_HEADER", "ACT_SIZE", "TEN_SIZE", "PATH_SIZE"]
