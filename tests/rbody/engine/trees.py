"""Random kinematic trees for the multibody tests: every joint kind, several hinges and slides on one
body, welded bodies, random inertias, axes, offsets, damping, stiffness, armature and ref."""

from __future__ import annotations

import numpy as np

from rbody import Body, Inertia, Joint, Layout
from rbody.motion import quat_normalize


def random_inertia(rng: np.random.Generator) -> Inertia:
    """A positive-definite tensor obeying the triangle inequality, turned at random, off-centre com."""
    moments = np.sort(rng.uniform(0.2, 1.0, 3))
    moments[2] = min(moments[2], 0.99 * (moments[0] + moments[1]))
    axes, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return Inertia(float(rng.uniform(0.5, 2.0)), rng.uniform(-0.3, 0.3, 3), axes @ np.diag(moments) @ axes.T)


def random_tree(rng: np.random.Generator, bodies: int, *, kinds=("hinge", "slide", "ball", "free", "weld"),
                passive: bool = True) -> Layout:
    """A tree of `bodies` bodies; each body's joints drawn from `kinds` ("weld": no joint; free only on
    children of the world; "multi": two or three hinges/slides on the body)."""
    out_bodies, out_joints = [], []
    for i in range(bodies):
        parent = "world" if i == 0 or rng.random() < 0.2 else f"b{rng.integers(0, i)}"
        choices = [k for k in kinds if k != "free" or parent == "world"]
        kind = str(rng.choice(choices))
        quat = quat_normalize(rng.normal(size=4))
        out_bodies.append(Body(f"b{i}", random_inertia(rng), parent=parent, pos=tuple(rng.uniform(-0.5, 0.5, 3)),
                               quat=tuple(quat)))
        names = {"weld": [], "multi": [str(rng.choice(["hinge", "slide"])) for _ in range(int(rng.integers(2, 4)))]}
        sequence = names.get(kind, [kind])
        if kind == "ball" and rng.random() < 0.5:
            sequence = [str(rng.choice(["hinge", "slide"])), "ball"]
        for k, joint_kind in enumerate(sequence):
            extra = {}
            if passive:
                extra = dict(damping=float(rng.uniform(0, 0.5)), armature=float(rng.uniform(0, 0.1)))
                if joint_kind in ("hinge", "slide"):
                    extra.update(stiffness=float(rng.uniform(0, 2)), springref=float(rng.uniform(-0.5, 0.5)),
                                 ref=float(rng.uniform(-0.5, 0.5)))
            if joint_kind in ("hinge", "slide"):
                qpos0, qvel0 = float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1))
            elif joint_kind == "ball":
                qpos0, qvel0 = tuple(quat_normalize(rng.normal(size=4))), tuple(rng.uniform(-1, 1, 3))
            else:
                qpos0, qvel0 = 0.0, tuple(rng.uniform(-1, 1, 6))
            out_joints.append(Joint(f"j{i}_{k}", joint_kind, f"b{i}", axis=tuple(rng.normal(size=3)),
                                    anchor=tuple(rng.uniform(-0.3, 0.3, 3)), qpos0=qpos0, qvel0=qvel0, **extra))
    return Layout(bodies=tuple(out_bodies), joints=tuple(out_joints))
