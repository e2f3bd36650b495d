"""A contact's margin (Contact.margin; MJCF's margin, MuJoCo's inflation of the surfaces since 3.9): the pair is held
at distance >= margin, exactly, in both schemes; MJCF's geom margins sum, a <pair>'s replaces them, <flag override>'s
o_margin replaces every one; gap changes nothing in the rigid limit; MuJoCo, given the exported margin, pushes
towards the same distance (softly)."""

import numpy as np
import pytest

import rbody
from rbody import Body, Contact, Joint, Layout, Scene, Shape
from rbody.inertia import Inertia
from rbody.mjcf import MJCFError

G = 9.81
R = 0.1


def ball_scene(z0, margin, restitution=0.0, t_end=1.0, shape=None, inertia=None):
    shape = shape or Shape("ball", "sphere", (R,))
    body = Body("b", inertia or Inertia.solid_sphere(1.0, R), shapes=(shape,), pos=(0.0, 0.0, z0))
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "b"),), fixed=(Shape("floor", "plane", (0, 0)),),
                    contacts=(Contact("floor", shape.name, friction=0.5, restitution=restitution, margin=margin),))
    return Scene.from_layout(layout, t_end=t_end)


@pytest.mark.parametrize("method", ["moreau", "rk4"])
def test_a_ball_rests_at_its_margin(method):
    margin = 0.01
    run = rbody.simulate(ball_scene(R + margin, margin), dt=1e-3, method=method)
    np.testing.assert_allclose(run["b.com"][:, 2], R + margin, rtol=0, atol=1e-15)
    np.testing.assert_allclose(run["contact_distance"][-1, 0], 0.0, rtol=0, atol=1e-15)  # the gap: distance less margin
    np.testing.assert_allclose(run["contact_normal_force"][-1, 0], G, rtol=1e-12)


def test_a_dropped_ball_lands_at_its_margin_at_the_closed_forms_time():
    """Event-driven: the impact at sqrt(2 (z0 - r - margin) / g); with e = 0.5 it leaves at half the speed."""
    margin, z0 = 0.05, 1.0
    run = rbody.simulate(ball_scene(z0, margin, restitution=0.5, t_end=0.6), dt=1e-3, method="rk4")
    t_impact = np.sqrt(2 * (z0 - R - margin) / G)
    v = run["b.velocity"][:, 2]
    up = run.t[np.argmax(v > 0)]  # the first sample after the bounce
    assert t_impact <= up <= t_impact + 1e-3
    after = run.t > t_impact
    # after the bounce: z = r + margin + (e v) (t - t_i) - g (t - t_i)^2 / 2, v = g t_i
    tau = run.t[after] - t_impact
    expected = R + margin + 0.5 * G * t_impact * tau - 0.5 * G * tau ** 2
    np.testing.assert_allclose(run["b.com"][after, 2], expected, rtol=0, atol=1e-10)
    assert run["b.com"][:, 2].min() >= R + margin - 1e-12


def test_time_stepping_lands_a_dropped_box_at_its_margin():
    margin = 0.02
    box = Shape("box", "box", (0.1, 0.1, 0.1))
    run = rbody.simulate(ball_scene(0.4, margin, shape=box, inertia=Inertia.box(1.0, (0.2, 0.2, 0.2)),
                                    t_end=1.0), dt=1e-3)
    z = run["b.com"][:, 2]
    assert z.min() >= 0.1 + margin - 1e-13
    np.testing.assert_allclose(z[-1], 0.1 + margin, rtol=0, atol=1e-13)
    np.testing.assert_allclose(run["contact_normal_force"][-1].sum(), G, rtol=1e-12)


def test_a_far_pair_within_its_margin_is_not_culled():
    """The broad phase's bound is less the margin: a ball 0.3 m above the floor with margin 0.35 is pushed out to
    it at once (the projection), not culled as apart."""
    run = rbody.simulate(ball_scene(R + 0.3, 0.35, t_end=0.05), dt=1e-3)
    np.testing.assert_allclose(run["b.com"][1:, 2], R + 0.35, rtol=0, atol=1e-12)


def test_negative_margin_refused():
    with pytest.raises(ValueError, match=r"margin=-0.01: must be >= 0"):
        Contact("floor", "ball", margin=-0.01)


MJCF = """<mujoco>{option}<worldbody>
<geom name="floor" type="plane" size="0 0 1" margin="{floor}" gap="{gap}"/>
<body name="b" pos="0 0 0.5"><freejoint/><geom name="ball" type="sphere" size="0.1" margin="{ball}"/></body>
</worldbody>{contact}</mujoco>"""


def contacts_of(tmp_path, floor=0.0, ball=0.0, gap=0.0, option="", contact=""):
    path = tmp_path / "margin.xml"
    path.write_text(MJCF.format(floor=floor, ball=ball, gap=gap, option=option, contact=contact))
    return rbody.mjcf.layout_from_mjcf(path).layout.contacts


def test_mjcf_margins_sum_a_pair_replaces_them_and_override_replaces_all(tmp_path):
    (contact,) = contacts_of(tmp_path, floor=0.01, ball=0.02, gap=0.5)
    assert contact.margin == pytest.approx(0.03, abs=1e-17)
    pair = '<contact><pair geom1="floor" geom2="ball" margin="0.005"/></contact>'
    (contact,) = contacts_of(tmp_path, floor=0.01, ball=0.02, contact=pair)
    assert contact.margin == 0.005
    override = '<option o_margin="0.007"><flag override="enable"/></option>'
    (contact,) = contacts_of(tmp_path, floor=0.01, ball=0.02, option=override)
    assert contact.margin == 0.007
    with pytest.raises(MJCFError, match=r"line 3.*margin='-0.01': rbody needs a contact margin >= 0"):
        contacts_of(tmp_path, ball=-0.01)


def test_mujoco_given_the_exported_margin_rests_near_it(tmp_path):
    """MuJoCo's soft contact pushes towards the same distance: its ball rests within its softness's sink (a few
    1e-4 m, the finding of the contact sweep) of r + margin, where rbody rests on it exactly."""
    mujoco = pytest.importorskip("mujoco")
    margin = 0.01
    scene = ball_scene(R + margin, margin, t_end=1.0)
    xml = rbody.to_mjcf(scene, dt=1e-3)
    assert 'margin="0.01"' in xml
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_resetData(model, data)
    data.qpos[:3] = (0.0, 0.0, R + margin)
    for _ in range(1000):
        mujoco.mj_step(model, data)
    sink = R + margin - data.qpos[2]
    assert 0 < sink < 1e-3, sink
    run = rbody.simulate(scene, dt=1e-3)
    assert abs(run["b.com"][-1, 2] - (R + margin)) <= 1e-15
