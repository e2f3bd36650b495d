"""A foot of two splayed capsules (their four ends not coplanar, as on dm_control's humanoid) dropped tilted onto a
floor: the four ends close within one step at different gaps. With the contacts' points midway between the
surfaces the landing step had no solution (the foot's turning gave the raised ends tangential velocities no
sticking impulses cancel: a SimulationError in 9 of these 12 cases); with the points on the floor, where a closing
contact touches, every case lands and comes to rest, nothing passing into the floor."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.inertia import Inertia
from rbody.motion import quat_multiply


def about_z(angle):
    return np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)])


def foot(tilt, drop, friction, splay=0.3):
    """Two capsules along x (radii 0.03 and 0.027, half-lengths 0.1 and 0.09), turned by -+splay/2 about z and 3
    mm apart in height, on one 1 kg body tilted by `tilt` about (0.6, 0.8, 0), `drop` [m] above the floor."""
    along_x = np.array([np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0])
    first = Shape("c1", "capsule", (0.03, 0.1), pos=(0.0, 0.05, 0.0),
                  quat=tuple(quat_multiply(about_z(splay / 2), along_x)))
    second = Shape("c2", "capsule", (0.027, 0.09), pos=(0.01, -0.05, 0.003),
                   quat=tuple(quat_multiply(about_z(-splay / 2), along_x)))
    turn = (np.cos(tilt / 2), 0.6 * np.sin(tilt / 2), 0.8 * np.sin(tilt / 2), 0.0)
    body = Body("foot", Inertia.box(1.0, (0.25, 0.15, 0.06)), shapes=(first, second), pos=(0.0, 0.0, 0.03 + drop),
                quat=turn)
    return Layout(bodies=(body,), joints=(Joint("free", "free", "foot"),), fixed=(Shape("floor", "plane", (0, 0)),),
                  contacts=(Contact("floor", "c1", friction=friction), Contact("floor", "c2", friction=friction)))


@pytest.mark.parametrize("tilt", [0.05, 0.1, 0.2])
@pytest.mark.parametrize("friction", [0.5, 1.0])
@pytest.mark.parametrize("dt", [5e-3, 2e-3])
def test_splayed_foot_lands_and_rests(tilt, friction, dt):
    run = rbody.simulate(Scene.from_layout(foot(tilt, 0.05, friction), t_end=1.0), dt=dt)
    dist = run["contact_distance"]
    assert np.min(dist[np.isfinite(dist)]) >= -1e-13
    assert np.abs(run["foot.velocity"][-1]).max() <= 1e-15 and np.abs(run["foot.omega"][-1]).max() <= 1e-13
    assert run["contacts"][-1] >= 3
