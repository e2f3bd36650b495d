"""Bad input to contacts: refused before any work, naming the contact and what was expected."""

import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.engine.contacts.geometry import collide_pair
from rbody.errors import MethodNotApplicable
from rbody.inertia import Inertia


def layout_with(contact, shape=Shape("s", "sphere", (0.1,)), fixed=(Shape("floor", "plane", (0, 0)),)):
    ball = Body("ball", Inertia.solid_sphere(1.0, 0.1), shapes=(shape,), pos=(0, 0, 0.1))
    return Layout(bodies=(ball,), joints=(Joint("free", "free", "ball"),), fixed=fixed, contacts=(contact,))


@pytest.mark.parametrize("contact, shape, match", [
    (Contact("floor", "nothing"), Shape("s", "sphere", (0.1,)), r"shape_b='nothing' is not a shape of the layout"),
    (Contact("floor", "c"), Shape("c", "mesh", ()), r"mesh shape 'c' has no vertices: a mesh collides by the convex "
                                                    r"hull of Shape.vertices"),
])
def test_layout_contacts_refused(contact, shape, match):
    with pytest.raises(ValueError, match=match):
        Scene.from_layout(layout_with(contact, shape), t_end=1.0)


def test_pair_rbody_does_not_compute_refused():
    """Two planes (a plane on a body: a Layout allows it, MuJoCo does not) have no contact function."""
    with pytest.raises(ValueError, match=r"contact 'floor'/'p': rbody computes contacts of plane with sphere.*"
                                         r"not plane-plane"):
        Scene.from_layout(layout_with(Contact("floor", "p"), Shape("p", "plane", (1.0, 1.0))), t_end=1.0)


def test_two_world_shapes_refused():
    fixed = (Shape("floor", "plane", (0, 0)), Shape("rock", "sphere", (0.1,)))
    with pytest.raises(ValueError, match="both shapes are on 'world'"):
        Scene.from_layout(layout_with(Contact("floor", "rock"), fixed=fixed), t_end=1.0)


def test_contact_fields_checked():
    for condim in (2, 5, True, 3.5):
        with pytest.raises(ValueError, match=f"condim={condim!r}, expected 1 .*3 .*4 .*or 6"):
            Contact("a", "b", condim=condim)
    for field in ("torsion", "rolling"):
        with pytest.raises(ValueError, match=field):
            Contact("a", "b", condim=6, **{field: -1e-3})
    with pytest.raises(ValueError, match="restitution"):
        Contact("a", "b", restitution=1.5)
    with pytest.raises(ValueError, match="friction"):
        Contact("a", "b", friction=-0.1)


def test_contacts_run_by_the_constraint_layers_schemes_only():
    """Time-stepping (moreau) by default, event-driven (rk4) or MuJoCo's integrators as the time-stepping's free
    motion on request; any other integrator is refused."""
    scene = Scene.from_layout(layout_with(Contact("floor", "s", friction=0.5)), t_end=0.01)
    assert scene.methods == ("moreau", "rk4", "mujoco_euler", "implicitfast", "implicit")
    with pytest.raises(MethodNotApplicable, match="moreau"):
        rbody.simulate(scene, dt=1e-3, method="verlet")


def test_geometry_refuses_unknown_kinds_and_pairs():
    import numpy as np

    with pytest.raises(ValueError, match="geom kind 'cone'"):
        collide_pair("cone", [0, 0, 0], np.eye(3), [1], "sphere", [0, 0, 0], np.eye(3), [1])
    with pytest.raises(ValueError, match="'plane' and 'plane'"):
        collide_pair("plane", [0, 0, 0], np.eye(3), [], "plane", [0, 0, 0], np.eye(3), [])
