"""Joint: the roll kind's own fields (radius, normal) are checked on construction."""

import pytest

from rbody.layout import Joint


def test_roll_joint_keeps_its_radius_and_unit_normal():
    joint = Joint("wheel", "roll", "disc", axis=(0, 2, 0), normal=(0, 0, 3), radius=0.25)
    assert joint.radius == 0.25
    assert joint.axis == (0.0, 1.0, 0.0)
    assert joint.normal == (0.0, 0.0, 1.0)
    assert tuple(joint.line) == (1.0, 0.0, 0.0)  # l = y x z: the centre moves along +x for q' > 0


@pytest.mark.parametrize("radius", [0.0, -0.1])
def test_roll_joint_refuses_a_radius_that_is_not_positive(radius):
    with pytest.raises(ValueError, match="radius"):
        Joint("wheel", "roll", "disc", axis=(0, 1, 0), radius=radius)


def test_roll_joint_refuses_a_normal_along_its_axis():
    with pytest.raises(ValueError, match="not perpendicular"):
        Joint("wheel", "roll", "disc", axis=(0, 1, 0), normal=(0, 1, 1), radius=0.1)


def test_radius_is_refused_on_other_kinds():
    with pytest.raises(ValueError, match="only for roll joints"):
        Joint("pin", "hinge", "rod", axis=(0, 1, 0), radius=0.1)


def _disc_on_incline(com_offset: float):
    """A disc (radius 0.3 m, 2 kg) rolling down a 0.4 rad incline; its centre of mass com_offset [m] off the axis."""
    import numpy as np

    from rbody.inertia import Inertia
    from rbody.layout import Body, Layout
    from rbody.scene import Scene

    alpha, radius, mass = 0.4, 0.3, 2.0
    normal = (np.sin(alpha), 0.0, np.cos(alpha))
    inertia = Inertia(mass=mass, com=(com_offset, 0.0, 0.0),
                      tensor=np.diag([0.25, 0.5, 0.25]) * mass * radius**2)
    body = Body("disc", inertia, pos=tuple(radius * np.array(normal)))
    joint = Joint("roll", "roll", "disc", axis=(0, 1, 0), normal=normal, radius=radius)
    return Scene.from_layout(Layout(bodies=(body,), joints=(joint,)), t_end=1.0), alpha, radius


def test_a_centred_rolling_disc_takes_the_symplectic_methods_and_verlet_is_exact():
    """Constant acceleration g sin(alpha) / (1 + k) (the chapter's rolling disc, k = 1/2): verlet is exact for it."""
    import numpy as np

    from rbody.simulation import simulate

    scene, alpha, radius = _disc_on_incline(0.0)
    assert scene.symplectic_applies == ""
    assert "verlet" in scene.methods
    run = simulate(scene, dt=0.01, method="verlet")
    t = run.t
    angle = 0.5 * 9.81 * np.sin(alpha) / (1.5 * radius) * t**2
    np.testing.assert_allclose(run["qpos"][:, 0], angle, rtol=1e-12, atol=1e-14)


def test_an_eccentric_rolling_disc_is_refused_the_symplectic_methods():
    scene, _, _ = _disc_on_incline(0.05)
    assert "off its axis" in scene.symplectic_applies
    assert "verlet" not in scene.methods
