"""Results that do not depend on where a model stands: every tree is computed about its own origin
(rbody/engine/multibody.py, "Precision"; rbody/engine/planar.py), so the same pendulum or tumbling body a million
metres from the world origin moves as it does at it. Before, the spatial algebra about the world origin lost
|x| / size of the digits: a double pendulum at 1e5 m ended 3.7e-6 rad off, at 1e6 m its mass matrix was taken
for singular."""

from __future__ import annotations

import numpy as np
import pytest

import rbody
from rbody import Body, Inertia, Joint, Layout, Scene
from rbody.engine import multibody as mb


def double_pendulum(origin: float, elbow_axis) -> Scene:
    upper = Body("upper", Inertia.box(1.0, [0.05, 0.05, 0.8]).translated([0, 0, -0.4]), pos=(origin, -origin, origin))
    lower = Body("lower", Inertia.box(0.5, [0.05, 0.05, 0.5]).translated([0, 0, -0.25]), parent="upper",
                 pos=(0, 0, -0.8))
    layout = Layout(bodies=(upper, lower), joints=(Joint("shoulder", "hinge", "upper", axis=(0, 1, 0), qpos0=1.0),
                                                  Joint("elbow", "hinge", "lower", axis=elbow_axis, qpos0=0.5)))
    return Scene.from_layout(layout, t_end=1.0)


@pytest.mark.parametrize("origin", [1e5, 1e6, 1e8])
@pytest.mark.parametrize("elbow_axis", [(0, 1, 0), (1, 1, 0)], ids=["planar path", "3-D path"])
def test_a_pendulum_far_away_moves_as_at_the_origin(origin, elbow_axis):
    near = rbody.simulate(double_pendulum(0.0, elbow_axis), dt=1e-3, method="rk4")
    far = rbody.simulate(double_pendulum(origin, elbow_axis), dt=1e-3, method="rk4")
    assert np.max(np.abs(far["qpos"] - near["qpos"])) <= 1e-10  # rad, over 1 s (the engine-core issue's goal)
    assert np.max(np.abs(far["qvel"] - near["qvel"])) <= 1e-9
    # the world positions follow: the same motion, moved by the origin (to the spacing of floats there)
    shift = np.array([origin, -origin, origin])
    assert np.max(np.abs(far["lower.com"] - shift - near["lower.com"])) <= 4 * np.spacing(origin)


def test_a_free_body_far_away_tumbles_as_at_the_origin():
    def tumbling(origin: float) -> Scene:
        body = Body("box", Inertia.box(2.0, [0.1, 0.4, 0.9]), pos=(origin, origin, -origin))
        joint = Joint("free", "free", "box", qvel0=(1.0, -2.0, 3.0, 0.3, 5.0, 0.2))
        return Scene.from_layout(Layout(bodies=(body,), joints=(joint,)), t_end=1.0, gravity=9.81)

    near, far = (rbody.simulate(tumbling(x), dt=1e-3, method="rk4") for x in (0.0, 1e6))
    np.testing.assert_array_equal(far["box.quat"], near["box.quat"])
    np.testing.assert_array_equal(far["box.omega"], near["box.omega"])
    # the position itself is a coordinate of the state, 1e6 + x: each of the 1000 steps rounds its sum to the
    # spacing of floats there (1.2e-10 m), as any float64 state would (MuJoCo's qpos too)
    moved = far["box.com"] - np.array([1e6, 1e6, -1e6])
    assert np.max(np.abs(moved - near["box.com"])) <= 1000 * np.spacing(1e6)


def test_the_energy_keeps_its_world_meaning():
    """Potential energy is m g z with z in the world: the far pendulum's is the near one's plus M g z0."""
    near = double_pendulum(0.0, (0, 1, 0))
    far = double_pendulum(1e3, (0, 1, 0))
    e_near, e_far = (rbody.simulate(s, dt=1e-3, method="rk4", t_end=0.01)["energy"] for s in (near, far))
    np.testing.assert_allclose(e_far - e_near, 1.5 * 9.81 * 1e3, rtol=1e-12)


def test_the_workspace_is_cut_to_its_declared_size():
    """_views cuts the arrays of one evaluation from the workspace: the last (scratch) ends where workspace_size
    says the workspace ends, for trees with every joint kind."""
    scene = double_pendulum(0.0, (1, 1, 0))
    ball = Body("ball", Inertia.solid_sphere(1.0, 0.1), parent="lower", pos=(0, 0, -0.5))
    free = Body("free", Inertia.box(1.0, [0.1, 0.2, 0.3]), pos=(1, 1, 1))
    layout = Layout(bodies=scene.tree.bodies + (ball, free),
                    joints=scene.tree.joints + (Joint("b", "ball", "ball"), Joint("f", "free", "free")))
    for tree in (scene.tree, layout):
        model = rbody.Multibody(tree)
        p = np.array(model.params)
        size = mb.workspace_size(p)
        w = np.zeros(size)
        views = mb._views(p, w)
        end = views.scratch.ctypes.data + views.scratch.nbytes
        assert end == w.ctypes.data + w.nbytes
