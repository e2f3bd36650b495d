"""Constraints read from MJCF (rbody.mjcf.constraints) and given from Python (rbody.layout): limits, dry friction,
restitution and equalities, each compared with what MuJoCo's compiler makes of the same file."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from rbody import Equality, Joint
from rbody.mjcf import MJCFError, layout_from_mjcf
from rbody.mjcf.frames import quat_matrix, quat_product

OFF = '<option><flag contact="disable"/></option>'

LINKAGE = f"""<mujoco>{OFF}
<custom><numeric name="rbody.restitution" data="0.25"/><numeric name="rbody.restitution.crank" data="0.5"/></custom>
<default><equality solref="0.01 1"/><joint frictionloss="0.05"/></default>
<worldbody>
  <body name="crank" euler="0 20 0"><joint name="crank" axis="0 1 0" range="-30 40" margin="0.1" frictionloss="0.2"/>
    <geom type="capsule" fromto="0 0 0 0 0 -1" size="0.02"/>
    <body name="frame" pos="0 0 -1" euler="10 0 0"><site name="s1" pos="0.1 0 0" euler="0 0 30"/>
      <body name="coupler"><joint name="coupler" axis="0 1 0" limited="false" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 1 0 0" size="0.02"/></body></body></body>
  <body name="rocker" pos="1 0 0" quat="0.9 0.1 0.2 0.3"><joint name="rocker" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0 0 -1" size="0.02"/>
    <site name="s2" pos="0 0 -1" euler="0 10 0"/>
    <body name="arm" pos="0 0.2 0"><joint name="ball" type="ball" range="0 60"/><geom size="0.05"/></body></body>
</worldbody>
<equality>
  <connect name="loop" body1="coupler" body2="rocker" anchor="1 0 0"/>
  <joint joint1="crank" joint2="rocker" polycoef="0.1 2 0.3 0 0" active="false"/>
  <weld site1="s1" site2="s2"/>
  <weld body1="arm" anchor="0.1 0.2 0.3"/>
  <weld body1="coupler" body2="rocker" relpose="0.1 0.2 0.3 0.5 0.5 0.5 0.5" anchor="0.3 0 0"/>
</equality></mujoco>"""


def world_poses(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return data.xpos.copy(), data.xquat.copy()


def test_limits_friction_and_restitution_are_mujocos_and_the_custom_numerics():
    read = layout_from_mjcf(LINKAGE)
    model = mujoco.MjModel.from_xml_string(LINKAGE)
    joints = {j.name: j for j in read.layout.joints}
    lo, hi = model.jnt_range[0]
    assert joints["crank"].range == pytest.approx((lo + 0.1, hi - 0.1), rel=1e-15)  # range less margin
    assert joints["coupler"].range is None  # limited="false"
    assert joints["rocker"].range is None   # no range
    assert joints["ball"].range == pytest.approx((0.0, math.radians(60)), rel=1e-15)
    for name, joint in joints.items():
        dof = model.jnt_dofadr[model.joint(name).id]
        assert joint.frictionloss == model.dof_frictionloss[dof]
    assert joints["crank"].frictionloss == 0.2 and joints["rocker"].frictionloss == 0.05  # its class's default
    assert joints["crank"].restitution == 0.5 and joints["rocker"].restitution == 0.25
    assert read.limits == {"crank": joints["crank"].range, "ball": joints["ball"].range}
    assert any("rigidly" in note for note in read.notes)  # the equalities' solref


def test_equalities_hold_at_mujocos_reference_configuration():
    """Every equality read is satisfied at MuJoCo's qpos0 (MuJoCo completes connect and weld there), with the
    folded body 'frame' moved onto its carrier 'crank'; the relpose given keeps its own pose."""
    read = layout_from_mjcf(LINKAGE)
    model = mujoco.MjModel.from_xml_string(LINKAGE)
    xpos, xquat = world_poses(model)
    ids = {name: model.body(name).id for name in ("crank", "coupler", "rocker", "arm")}
    ids["world"] = 0
    loop, coupling, sites, arm, given = read.layout.equalities
    assert (loop.name, loop.kind, loop.body1, loop.body2) == ("loop", "connect", "coupler", "rocker")
    p1 = xpos[ids["coupler"]] + quat_matrix(xquat[ids["coupler"]]) @ loop.anchor
    p2 = xpos[ids["rocker"]] + quat_matrix(xquat[ids["rocker"]]) @ loop.anchor2
    np.testing.assert_allclose(p1, p2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(loop.anchor2, model.eq_data[0, 3:6], rtol=0, atol=1e-15)  # MuJoCo's own
    assert (coupling.kind, coupling.joint1, coupling.joint2, coupling.active) == ("joint", "crank", "rocker", False)
    assert coupling.polycoef == (0.1, 2.0, 0.3, 0.0, 0.0)
    assert (sites.kind, sites.body1, sites.body2) == ("weld", "crank", "rocker")  # site s1 is on the folded frame
    for weld in (arm,):
        b1, b2 = ids[weld.body1], ids[weld.body2]
        point2 = xpos[b2] + quat_matrix(xquat[b2]) @ np.array(weld.anchor)
        point1 = xpos[b1] + quat_matrix(xquat[b1]) @ np.array(weld.relpose[:3])
        np.testing.assert_allclose(point1, point2, rtol=0, atol=1e-14)
        q = quat_product(xquat[b1], weld.relpose[3:])
        assert abs(abs(float(q @ xquat[b2])) - 1) < 1e-14
    site1, site2 = model.site("s1").id, model.site("s2").id
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    np.testing.assert_allclose(xpos[ids["crank"]] + quat_matrix(xquat[ids["crank"]]) @ sites.relpose[:3],
                               data.site_xpos[site1], rtol=0, atol=1e-14)
    np.testing.assert_allclose(xpos[ids["rocker"]] + quat_matrix(xquat[ids["rocker"]]) @ sites.anchor,
                               data.site_xpos[site2], rtol=0, atol=1e-14)
    # the site weld: body1's site frame on body2's, q_c1 relquat q_c2^-1 q_site2 = q_site1 (world orientations)
    site_quat = np.empty((2, 4))
    for k, site in enumerate((site1, site2)):
        mujoco.mju_mat2Quat(site_quat[k], data.site_xmat[site])
    inverse = xquat[ids["rocker"]] * np.array([1, -1, -1, -1])
    turned = quat_product(quat_product(quat_product(xquat[ids["crank"]], sites.relpose[3:]), inverse), site_quat[1])
    assert abs(abs(float(turned @ site_quat[0])) - 1) < 1e-14
    assert (arm.body1, arm.body2) == ("arm", "world")
    assert given.relpose == pytest.approx((0.1, 0.2, 0.3, 0.5, 0.5, 0.5, 0.5), rel=1e-15)
    np.testing.assert_allclose(given.relpose, model.eq_data[4, 3:10], rtol=0, atol=1e-15)


@pytest.mark.parametrize("flag, gone", [("limit", "range"), ("frictionloss", "frictionloss"),
                                        ("equality", "equalities"), ("constraint", "all")])
def test_disabled_flags_drop_their_constraints(flag, gone):
    xml = LINKAGE.replace(OFF, f'<option><flag contact="disable" {flag}="disable"/></option>')
    layout = layout_from_mjcf(xml).layout
    ranges = [j.range for j in layout.joints if j.range is not None]
    friction = [j.frictionloss for j in layout.joints if j.frictionloss]
    assert (not ranges) == (gone in ("range", "all"))
    assert (not friction) == (gone in ("frictionloss", "all"))
    assert (not layout.equalities) == (gone in ("equalities", "all"))


def test_python_description_defaults_keep_every_layout_as_it_was():
    joint = Joint("j", "hinge", "b")
    assert (joint.range, joint.frictionloss, joint.restitution) == (None, 0.0, 0.0)
    ball = Joint("s", "ball", "b", range=(0, 1.0))
    assert ball.range == (0.0, 1.0)


@pytest.mark.parametrize("kwargs, match", [
    (dict(kind="free", range=(-1, 1)), "a free joint has no range"),
    (dict(kind="ball", range=(0.1, 1)), r"\(0, theta_max\)"),
    (dict(kind="ball", range=(0, 4)), r"theta_max <= pi"),
    (dict(kind="hinge", range=(1, 1)), "lo < hi"),
    (dict(kind="hinge", range=(0, float("inf"))), "finite|inf"),
    (dict(kind="slide", frictionloss=-0.1), "frictionloss"),
    (dict(kind="slide", restitution=1.5), "restitution"),
])
def test_bad_joint_constraints_are_refused_naming_the_joint(kwargs, match):
    with pytest.raises(ValueError, match=match) as error:
        Joint("j", body="b", **kwargs)
    assert "joint 'j'" in str(error.value)


@pytest.mark.parametrize("kwargs, match", [
    (dict(kind="rope"), "kind='rope'"),
    (dict(kind="connect"), "needs body1"),
    (dict(kind="weld", body1="a", body2="a"), "both 'a'"),
    (dict(kind="joint", joint1="j", joint2="j"), "both 'j'"),
    (dict(kind="connect", body1="a", anchor=(0, 0)), "anchor"),
    (dict(kind="weld", body1="a", relpose=(0, 0, 0, 0, 0, 0, 0)), "quaternion"),
    (dict(kind="joint", joint1="j", polycoef=(0, 1)), "polycoef"),
])
def test_bad_equalities_are_refused_naming_them(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Equality("e", **kwargs)


def test_tendon_equality_is_read_and_its_tendons_must_exist():
    body = "<body name='b'><joint name='q'/><geom size='0.1'/></body>"
    tendon = "<tendon><fixed name='t'><joint joint='q' coef='2'/></fixed></tendon>"
    xml = (f"<mujoco>{OFF}<worldbody>{body}</worldbody>{tendon}<equality><tendon tendon1='{{}}' polycoef='0.1 0 0 0 0' "
           "active='false'/></equality></mujoco>")
    with pytest.raises(MJCFError, match="tendon 'nope' is not a tendon of the model"):
        layout_from_mjcf(xml.format("nope"))
    read = layout_from_mjcf(xml.format("t"))
    assert read.layout.equalities == (Equality("equality0", "tendon", tendon1="t", polycoef=(0.1, 0, 0, 0, 0),
                                               active=False),)


def test_to_mjcf_writes_the_constraints_and_reads_them_back():
    """rbody.to_mjcf writes ranges, frictionloss, restitution (the custom numeric) and equalities (connect and weld
    by sites at the points rbody joins, joint couplings as they are); MuJoCo compiles them, its equality holds at the
    state written, and from_mjcf reads back the same constraints."""
    from rbody import Body, Inertia, Layout, Scene, from_mjcf, to_mjcf

    rod = Inertia(1.0, (0, 0, -0.5), np.diag([1 / 12, 1 / 12, 1e-6]))
    bodies = (Body("a", rod), Body("b", rod, pos=(0.4, 0, 0)), Body("c", rod, parent="a", pos=(0, 0, -1)))
    joints = (Joint("qa", "hinge", "a", axis=(0, 1, 0), range=(-1, 1), frictionloss=0.2, restitution=0.5),
              Joint("qb", "hinge", "b", axis=(0, 1, 0)), Joint("qc", "ball", "c", range=(0, 1.0)))
    equalities = (Equality("tie", "joint", joint1="qb", joint2="qa", polycoef=(0, 0.5, 0, 0, 0)),
                  Equality("pin", "connect", body1="c", body2="b", anchor=(0.4, 0, -0.2)),
                  Equality("off", "weld", body1="b", active=False))
    scene = Scene.from_layout(Layout(bodies=bodies, joints=joints, equalities=equalities), t_end=1.0)
    xml = to_mjcf(scene)
    model = mujoco.MjModel.from_xml_string(xml)
    assert model.jnt_limited[0] and tuple(model.jnt_range[0]) == (-1.0, 1.0) and model.dof_frictionloss[0] == 0.2
    assert model.neq == 3 and list(model.eq_active0) == [1, 1, 0]
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pin1, pin2 = data.site("pin_site1").xpos, data.site("pin_site2").xpos
    np.testing.assert_allclose(pin1, pin2, rtol=0, atol=1e-15)  # completed where rbody completes it
    back = from_mjcf(xml)
    read = {j.name: j for j in back.tree.joints}
    assert [read[j.name].range for j in joints] == [j.range for j in joints]
    assert [read[j.name].restitution for j in joints] == [0.5, 0.0, 0.0]
    names = [(e.name, e.kind, e.active) for e in back.tree.equalities]
    assert names == [("tie", "joint", True), ("pin", "connect", True), ("off", "weld", False)]
    np.testing.assert_allclose(back.tree.equalities[1].anchor2, scene.constraint_table.equalities[1].anchor2,
                               rtol=0, atol=1e-15)
