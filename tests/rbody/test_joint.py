"""Joint: the roll kind's own fields (radius, normal) are checked on construction."""

import pytest

from rbody.scene import Joint


def test_roll_joint_keeps_its_radius_and_unit_normal():
    joint = Joint("wheel", "roll", "disc", axis=(0, 2, 0), normal=(0, 0, 3), radius=0.25)
    assert joint.radius == 0.25
    assert joint.axis == (0.0, 1.0, 0.0)
    assert joint.normal == (0.0, 0.0, 1.0)


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
