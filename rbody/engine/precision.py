"""What float64 can carry of a tree as the engine computes it: coordinates far from the origin, large hinge angles.

Digits lost far from the origin. The engine writes every spatial quantity about the world origin (rbody.engine.
multibody, "ground coordinates"): a body of mass m whose centre of mass is at x carries m |x|^2 in its inertia
about the origin, and the pivot D of a rotational degree of freedom (hinge, roll, ball, a free joint's rotations)
is what is left after sums of such terms cancel, down to the subtree's own inertia about the joint, L = sum over
the subtree of (m_b |x_b - a|^2 + trace I_b), a the joint's anchor. Each term is rounded to eps of its size, so
the pivot carries a relative error of about

    eps S / L,    S = sum over the subtree of m_b |x_b|^2,

and so does every acceleration computed from it (at 1e6 m from the origin with metre-scale bodies: 1e-4, and the
ABA's pivots fall below its singularity test: the model was refused as "the mass matrix is singular"). A tree is
refused, with that reason and the figures, when eps S / L passes LOST_DIGITS_LIMIT (1e-8: fewer than 8 digits
left). At the scene's construction x is where the bodies start; before a run, a body below a free or slide joint
may also travel (|v| t_end + g t_end^2 / 2 along its line of flight, added to |x|). MuJoCo works about each
tree's centre of mass instead; once rbody's engine is body-local (the engine-core issue) this check goes.

Hinge angles. A hinge or roll coordinate q is stored to its float64 spacing ulp(q) = 2^(floor(log2 |q|) - 52)
(0.125 rad at q = 1e15). A step that moves it by h w is then rounded to ulp(q)/2, every step. A scene is refused
when ulp(q) passes ANGLE_SPACING_LIMIT (2^-20 rad, |q| >= 2^33 = 8.6e9 rad), and a run when ulp(q) passes
STEP_ROUNDING_LIMIT (1e-6) of the angle one step moves, h w, w the larger of the joint's speed and the scene's
fastest rate: the rounding of the angle would then be more than a millionth of every step. The remedy is the
same angle reduced by whole turns (q mod 2 pi for a hinge without a spring).
"""

from __future__ import annotations

import math

import numpy as np


EPS = float(np.finfo(np.float64).eps)
LOST_DIGITS_LIMIT = 1e-8      # relative precision of the engine's pivots below which a tree is refused
ANGLE_SPACING_LIMIT = 2.0**-20  # rad: a hinge angle carried more coarsely than this is refused at construction
STEP_ROUNDING_LIMIT = 1e-6    # of the angle a step moves: the rounding of a hinge angle a run may carry
CHECKED_STATES = 64           # batch elements examined (those whose coordinates are largest)


def _largest_states(qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """At most CHECKED_STATES rows of qpos (B, nq), qvel (B, nv): those with the largest coordinates and speeds."""
    if qpos.shape[0] <= CHECKED_STATES:
        return qpos, qvel
    size = np.max(np.abs(qpos), axis=1) + np.max(np.abs(qvel), axis=1, initial=0.0)
    rows = np.argpartition(size, -CHECKED_STATES)[-CHECKED_STATES:]
    return qpos[rows], qvel[rows]


def _rotations(quat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices of unit quaternions (..., 4) (w, x, y, z)."""
    w, x, y, z = np.moveaxis(quat, -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def lost_digits(model, qpos: np.ndarray, qvel: np.ndarray, t_end: float = 0.0) -> tuple[float, str]:
    """(eps S / L, where) at its largest over the rotational degrees of freedom of `model` (a Multibody) and the
    states qpos (B, nq), qvel (B, nv) (module docstring); bodies below a free or slide joint travel for t_end [s].
    `where` names the joint, the body and the figures. (0, "") for a tree with no rotational degree of freedom.
    Cost linear in the bodies: each subtree's mass, centre of mass, inertia about that centre (the parallel-axis
    theorem, from differences of nearby points, which keep their digits far from the origin) and S are summed
    towards the root once."""
    arrays = model.arrays
    nb, nv = len(model.body_names), model.nv
    if nv == 0 or nb == 0:
        return 0.0, ""
    qpos, qvel = _largest_states(np.atleast_2d(qpos), np.atleast_2d(qvel))
    states = model.body_states(qpos, qvel)
    com, quat = states["com"], states["quat"]                     # (B, nb, 3), (B, nb, 4)
    # the description, in the engine's order (its body_names and joint_names): read from the Layout
    index = {name: i for i, name in enumerate(model.body_names)}
    bodies = {body.name: body for body in model.layout.bodies}
    joints = {joint.name: joint for joint in model.layout.joints}
    described = [bodies[name] for name in model.body_names]
    parent = np.array([index.get(body.parent, -1) for body in described])
    mass = np.array([body.inertia.mass for body in described])
    local_com = np.array([body.inertia.com for body in described], dtype=float).reshape(nb, 3)
    trace = np.array([np.trace(body.inertia.tensor) for body in described])
    joint_body = [index[joints[name].body] for name in model.joint_names]
    # how far each body may travel over the run: below a free or slide joint, |v| t + g t^2 / 2
    batch = qpos.shape[0]
    speed, moving = np.zeros((batch, nb)), np.zeros(nb, dtype=bool)
    for kind, body, dofadr in zip(arrays.joint_kinds, joint_body, arrays.dofadr):
        if kind in ("free", "slide"):
            width = 3 if kind == "free" else 1
            moving[body] = True
            speed[:, body] = np.maximum(speed[:, body], np.linalg.norm(qvel[:, int(dofadr):int(dofadr) + width], axis=1))
    for i in range(nb):  # parents come first: a body moves with everything above it
        if parent[i] >= 0:
            moving[i] |= moving[parent[i]]
            speed[:, i] = np.maximum(speed[:, i], speed[:, parent[i]])
    travel = np.where(moving, speed * t_end + 0.5 * abs(model.gravity) * t_end**2, 0.0)  # (B, nb)
    reach = np.linalg.norm(com, axis=2) + travel                                          # (B, nb)
    # subtree sums towards the root: mass M, centre C, inertia J about C (trace form), S = sum m reach^2
    total, centre = np.broadcast_to(mass, (batch, nb)).copy(), com.copy()
    inertia, world = np.broadcast_to(trace, (batch, nb)).copy(), mass * reach**2
    farthest = np.broadcast_to(np.arange(nb), (batch, nb)).copy()
    for i in range(nb - 1, -1, -1):
        k = parent[i]
        if k < 0:
            continue
        both = total[:, k] + total[:, i]
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(both > 0, total[:, i] / both, 0.0)
        offset = centre[:, i] - centre[:, k]                       # two nearby points: no digits lost
        inertia[:, k] += inertia[:, i] + total[:, k] * share * np.sum(offset**2, axis=1)  # parallel axes, combined
        centre[:, k] += share[:, None] * offset
        total[:, k] = both
        world[:, k] += world[:, i]
        far = reach[np.arange(batch), farthest[:, i]] > reach[np.arange(batch), farthest[:, k]]
        farthest[:, k] = np.where(far, farthest[:, i], farthest[:, k])
    rotation = _rotations(quat)                                                           # (B, nb, 3, 3)
    worst, where = 0.0, ""
    for d in range(nv):
        j = int(arrays.dof_joint[d])
        within = d - int(arrays.dofadr[j])  # which degree of freedom of its joint
        kind = arrays.joint_kinds[j]
        if kind == "slide" or (kind == "free" and within < 3):
            continue  # a translation's pivot is a mass: nothing cancels
        if within > 0 and kind in ("ball", "free") and (kind == "ball" or within > 3):
            continue  # the joint's other rotations: the same subtree, the same figures
        body = joint_body[j]
        anchor_local = np.asarray(joints[model.joint_names[j]].anchor, dtype=float)
        anchor = com[:, body] + np.einsum("bij,j->bi", rotation[:, body], anchor_local - local_com[body])
        local = inertia[:, body] + total[:, body] * np.sum((centre[:, body] - anchor) ** 2, axis=1)  # L, (B,)
        scale = world[:, body]                                                                      # S, (B,)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(local > 0, EPS * scale / local, 0.0)  # L = 0: singular of itself (check_pivots says so)
        b = int(np.argmax(ratio))
        if ratio[b] > worst:
            far = int(farthest[b, body])
            worst = float(ratio[b])
            where = (f"joint {model.joint_names[j]!r} of body {model.body_names[body]!r}: the subtree's inertia about "
                     f"the world origin, sum m |x|^2 = {scale[b]:.3g} kg m^2 (body {model.body_names[far]!r} "
                     f"{'reaches' if travel[b, far] else 'is'} {reach[b, far]:.3g} m from the origin"
                     f"{f' over the run, travelling {travel[b, far]:.3g} m' if travel[b, far] else ''}), against its "
                     f"own inertia about the joint, {local[b]:.3g} kg m^2")
    return worst, where


def lost_digits_problem(model, qpos: np.ndarray, qvel: np.ndarray, t_end: float = 0.0) -> str | None:
    """Why the engine cannot carry `model` at these states (str, with the figures), or None (module docstring)."""
    ratio, where = lost_digits(model, qpos, qvel, t_end)
    if ratio <= LOST_DIGITS_LIMIT:
        return None
    digits = max(0.0, -math.log10(ratio)) if ratio > 0 else 16.0
    return (f"its coordinates lose digits: {where}. The engine forms inertias about the world origin, so the "
            f"pivots of the articulated-body algorithm keep a relative precision of only eps x {ratio / EPS:.3g} = "
            f"{ratio:.2g} (about {digits:.0f} digits; the limit is {LOST_DIGITS_LIMIT:.0e}). Place the model near the "
            "origin (subtract its position from the bodies' pos and the free joints' qpos), or shorten the run; the "
            "engine will be body-local in a later version (rbody.engine.precision)")


def _angle_columns(model) -> list[tuple[str, int, int]]:
    """(joint name, qpos address, qvel address) of every hinge and roll joint."""
    return [(name, int(qa), int(da)) for name, kind, qa, da in zip(model.joint_names, model.arrays.joint_kinds,
                                                                    model.arrays.qposadr, model.arrays.dofadr)
            if kind in ("hinge", "roll")]


def angle_spacing_problem(model, qpos: np.ndarray) -> str | None:
    """Why a hinge or roll angle of qpos (B, nq) is too large for float64 to carry any step (str), or None."""
    qpos = np.atleast_2d(qpos)
    for name, qa, _ in _angle_columns(model):
        largest = float(np.max(np.abs(qpos[:, qa])))
        spacing = float(np.spacing(largest))
        if spacing > ANGLE_SPACING_LIMIT:
            return (f"joint {name!r}: its angle {largest:.6g} rad is carried by float64 only to its spacing "
                    f"{spacing:.3g} rad (beyond {ANGLE_SPACING_LIMIT:.3g} rad, |q| >= 2^33): every step of a run would "
                    f"be rounded to that; give the same angle reduced by whole turns (q mod 2 pi = "
                    f"{math.fmod(largest, 2 * math.pi):.6g} rad, where the joint has no spring)")
    return None


def angle_step_problem(model, qpos: np.ndarray, qvel: np.ndarray, dt: float, rate) -> str | None:
    """Why a run at step dt [s] cannot carry a hinge or roll angle of qpos (B, nq) (str), or None: its spacing
    passes STEP_ROUNDING_LIMIT of the angle a step moves, dt max(|qvel|, w); `rate` () -> w [1/s], the scene's
    fastest rate, asked for only when an angle's speed alone does not settle it."""
    qpos, qvel = np.atleast_2d(qpos), np.atleast_2d(qvel)
    fastest = None
    for name, qa, da in _angle_columns(model):
        spacing = np.spacing(np.abs(qpos[:, qa]))
        speed = np.abs(qvel[:, da])
        if np.all(spacing <= STEP_ROUNDING_LIMIT * dt * speed):
            continue
        if fastest is None:
            fastest = float(rate())
        moved = dt * np.maximum(speed, fastest)
        with np.errstate(divide="ignore", invalid="ignore"):
            share = np.where(moved > 0, spacing / moved, 0.0)
        b = int(np.argmax(share))
        if share[b] > STEP_ROUNDING_LIMIT:
            return (f"joint {name!r}: its angle {qpos[b, qa]:.6g} rad (batch element {b}) is carried by float64 only to "
                    f"{spacing[b]:.3g} rad, {share[b]:.2g} of the {moved[b]:.3g} rad a step of dt={dt:g} s moves it "
                    f"(beyond {STEP_ROUNDING_LIMIT:g}: every step would be rounded by that much); give the angle "
                    f"reduced by whole turns (q mod 2 pi = {math.fmod(float(qpos[b, qa]), 2 * math.pi):.6g} rad, where "
                    "the joint has no spring) or a larger step")
    return None


__all__ = ["lost_digits", "lost_digits_problem", "angle_spacing_problem", "angle_step_problem", "LOST_DIGITS_LIMIT",
           "ANGLE_SPACING_LIMIT", "STEP_ROUNDING_LIMIT"]
