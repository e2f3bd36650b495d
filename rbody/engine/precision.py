"""What float64 can carry of a tree as the engine computes it: large hinge angles.

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

ANGLE_SPACING_LIMIT = 2.0**-20  # rad: a hinge angle carried more coarsely than this is refused at construction
STEP_ROUNDING_LIMIT = 1e-6    # of the angle a step moves: the rounding of a hinge angle a run may carry


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


__all__ = ["angle_spacing_problem", "angle_step_problem", "ANGLE_SPACING_LIMIT", "STEP_ROUNDING_LIMIT"]
