"""Issue 23: wrong types in the description are a ValueError at construction naming the field, never an
AttributeError when the scene is built."""

from __future__ import annotations

import numpy as np
import pytest

from rbody import Body, Contact, Inertia, Joint, Layout, Scene, Shape

ROD = Inertia.rod(1.0, 1.0, "z")


@pytest.mark.parametrize("build, message", [
    (lambda: Body("a", 1.0), r"body 'a': inertia=1.0 is a float: expected an rbody.Inertia"),
    (lambda: Body(3, ROD), r"body: name=3 \(int\): expected a non-empty str"),
    (lambda: Body("a", ROD, parent=None), r"body 'a': parent=None \(NoneType\): expected a non-empty str"),
    (lambda: Body("a", ROD, shapes=Shape("s", "sphere", (0.1,))), r"body 'a': shapes=Shape\(.*expected a tuple"),
    (lambda: Body("a", ROD, shapes=("s",)), r"body 'a': shapes\[0\]='s' is a str: expected an rbody.Shape"),
    (lambda: Body("a", ROD, pos=(0, 0)), r"body 'a': pos has shape \(2,\): expected \(3,\)"),
    (lambda: Body("a", ROD, quat=(0, 0, 0, 0)), r"body 'a': quat=\[0.0, 0.0, 0.0, 0.0\] must be non-zero"),
    (lambda: Layout(bodies=(1, 2), joints=()), r"Layout bodies\[0\]=1 is a int: expected an rbody.Body"),
    (lambda: Layout(bodies=Body("a", ROD), joints=()), r"Layout bodies=Body\(.*expected a tuple of rbody.Body"),
    (lambda: Layout(bodies=(Body("a", ROD),), joints=("hinge",)), r"Layout joints\[0\]='hinge' is a str"),
    (lambda: Joint("j", "hinge", 5), r"joint 'j': body=5 \(int\): expected a non-empty str"),
    (lambda: Shape(None, "sphere", (0.1,)), r"shape: name=None"),
    (lambda: Contact("a", 2), r"contact: shape_b=2"),
])
def test_wrong_types_are_value_errors_naming_the_field(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_a_huge_wrong_value_is_not_echoed_whole():
    with pytest.raises(ValueError) as error:
        Body("a", "x" * 5_000_000)
    assert len(str(error.value)) < 400


def test_lists_and_arrays_are_kept_as_tuples_and_the_scene_builds():
    body = Body("a", ROD.translated([0, 0, -0.5]), pos=np.array([0.0, 0.0, 1.0]), quat=[1, 0, 0, 0])
    assert body.pos == (0.0, 0.0, 1.0) and body.quat == (1.0, 0.0, 0.0, 0.0)
    layout = Layout(bodies=[body], joints=[Joint("j", "hinge", "a", axis=(0, 1, 0))])
    assert isinstance(layout.bodies, tuple) and isinstance(layout.joints, tuple)
    assert Scene.from_layout(layout, t_end=1.0).multibody.nv == 1
