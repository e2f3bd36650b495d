"""pymunk runs a user's planar contact model (bodies on x and z slides and a y hinge, a floor plane): the same
MJCF file in rbody (event-driven contacts) and pymunk, each against the closed form. Findings recorded here:
pymunk rolls the thrown sphere at 5/7 v0 to round-off, and stops a sliding box or capsule v0 dt / 2 beyond
v0^2 / (2 mu g) (its positions advance with the velocity before each step: first order); rbody stops it there."""

import numpy as np
import pytest

import rbody
from validation.backends import pymunk as pymunk_backend

G = 9.81
MU, V0 = 0.3, 2.0
SHAPES = {
    "sphere": ('<geom name="s" type="sphere" size="0.1" mass="1" friction="0.3"/>', 0.1),
    "box": ('<geom name="s" type="box" size="0.2 0.1 0.05" mass="1" friction="0.3"/>', 0.05),
    "capsule": ('<geom name="s" type="capsule" size="0.05 0.2" quat="0.7071067811865476 0 0.7071067811865476 0" '
                'mass="1" friction="0.3"/>', 0.05),
}


def planar_scene(kind: str):
    geom, height = SHAPES[kind]
    xml = (f'<mujoco model="planar_{kind}"><worldbody><geom name="floor" type="plane" size="0 0 1" friction="0.3"/>'
           f'<body name="b" pos="0 0 {height}"><joint name="x" type="slide" axis="1 0 0"/>'
           f'<joint name="z" type="slide" axis="0 0 1"/><joint name="phi" type="hinge" axis="0 1 0"/>{geom}</body>'
           f'</worldbody></mujoco>')
    return rbody.from_mjcf(xml, t_end=1.0, qvel0=[V0, 0.0, 0.0])


def test_pymunk_checks_a_planar_contact_model_and_still_refuses_limits():
    pymunk_backend.check(planar_scene("box"))
    from rbody import Body, Joint, Layout, Scene, Shape
    from rbody.inertia import Inertia

    limited = Layout(bodies=(Body("b", Inertia.solid_sphere(1.0, 0.1), shapes=(Shape("s", "sphere", (0.1,)),)),),
                     joints=(Joint("x", "slide", "b", axis=(1, 0, 0), range=(-1.0, 1.0)),))
    with pytest.raises(NotImplementedError, match="joint limits"):
        pymunk_backend.check(Scene.from_layout(limited, t_end=1.0))


def test_thrown_sphere_rolls_at_five_sevenths_in_both():
    scene = planar_scene("sphere")
    run = pymunk_backend.run(scene, 1e-3, 1.0)
    native = rbody.simulate(scene, dt=1e-3, method="rk4")
    for trajectory in (run, native):
        assert abs(trajectory["qvel"][-1, 0] - 5 / 7 * V0) <= 1e-12
        assert abs(trajectory["qvel"][-1, 2] - 5 / 7 * V0 / 0.1) <= 1e-10   # spin about y: v / r
        assert np.abs(trajectory["qpos"][:, 1]).max() <= 1e-12              # the height stays r
    assert abs(native.events["time"][0] - 2 * V0 / (7 * MU * G)) <= 1e-10


@pytest.mark.parametrize("kind", ["box", "capsule"])
def test_sliding_body_stops_at_v0_squared_over_2_mu_g(kind):
    scene = planar_scene(kind)
    stop = V0 ** 2 / (2 * MU * G)
    native = rbody.simulate(scene, dt=1e-3, method="rk4")
    assert abs(native["qpos"][-1, 0] - stop) <= 1e-12
    assert np.abs(native["qpos"][:, 1:]).max() <= 1e-15                      # no sinking, no tipping
    overshoot = []
    for dt in (1e-3, 1e-4):
        run = pymunk_backend.run(scene, dt, 1.0)
        overshoot.append(run["qpos"][-1, 0] - stop)
        np.testing.assert_allclose(overshoot[-1], V0 * dt / 2, rtol=1e-3)   # the finding: v0 dt / 2 beyond
        assert np.abs(run["qpos"][:, 1]).max() <= 2e-11
