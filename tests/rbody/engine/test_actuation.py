"""Actuators and tendons (rbody.layout.Actuator, Tendon; rbody.engine.actuation; rbody.mjcf.actuators) against
MuJoCo's own computation on MJCF written here, closed forms, export round trips and every refusal."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import rbody
from rbody import Actuator, Body, Inertia, Joint, Layout, Scene, Tendon
from rbody.mjcf import MJCFError, layout_from_mjcf

# Every actuator rbody reads, on hinge, slide, ball and both kinds of tendon; class defaults shared across elements.
ARM = """
<mujoco model="arm">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="RK4"><flag contact="disable"/></option>
  <default>
    <joint damping="0.05"/>
    <default class="servo"><position kp="30" kv="2"/></default>
  </default>
  <worldbody>
    <body name="base" pos="0 0 1">
      <joint name="shoulder" axis="0 1 0" armature="0.01" range="-2 2"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <site name="s0" pos="0.2 0 0.05"/>
      <body name="upper" pos="0.4 0 0">
        <joint name="elbow" axis="0 1 0" springref="0.3" stiffness="1"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <site name="s1" pos="0.15 0.02 0.04"/>
        <body name="lower" pos="0.3 0 0">
          <joint name="wrist" type="ball" damping="0.02"/>
          <geom type="box" size="0.05 0.02 0.03" pos="0.05 0 0"/>
          <body name="slider" pos="0.1 0 0">
            <joint name="slide" type="slide" axis="1 0 0"/>
            <geom type="sphere" size="0.03"/>
            <site name="s2" pos="0 0 0.02"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <tendon>
    <fixed name="couple" stiffness="2" damping="0.3" springlength="0.1 0.2">
      <joint joint="shoulder" coef="1"/><joint joint="elbow" coef="-0.5"/>
    </fixed>
    <spatial name="cable" stiffness="5" damping="0.1">
      <site site="s0"/><site site="s1"/><site site="s2"/>
    </spatial>
  </tendon>
  <actuator>
    <position class="servo" name="p_sh" joint="shoulder" ctrlrange="-1 1" forcerange="-5 5"/>
    <position name="p_el" joint="elbow" kp="20" dampratio="0.7" timeconst="0.05"/>
    <motor name="m_wr" joint="wrist" gear="0.3 0.2 0.1"/>
    <velocity name="v_sl" joint="slide" kv="4"/>
    <intvelocity name="iv" joint="shoulder" kp="5" actrange="-0.5 0.5"/>
    <general name="g_t" tendon="couple" dyntype="filter" dynprm="0.1" gaintype="affine" gainprm="1 0.5 0.2"
             biastype="affine" biasprm="0.1 -1 -0.3" actearly="true"/>
    <damper name="d" joint="elbow" kv="0.5" ctrlrange="0 2"/>
    <motor name="m_cable" tendon="cable" gear="2"/>
    <general name="int" joint="slide" dyntype="integrator" gainprm="3" actrange="-1 1" actearly="true"/>
    <position name="p_tendon" tendon="couple" kp="4" dampratio="1.2" gear="1.5"/>
  </actuator>
</mujoco>
"""


def random_states(model, rng, count):
    for _ in range(count):
        q = model.qpos0 + rng.uniform(-0.6, 0.6, model.nq)
        for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
            if kind == "ball":
                quat = rng.normal(size=4)
                q[address:address + 4] = quat / np.linalg.norm(quat)
        yield (q, rng.uniform(-1, 1, model.nv), rng.uniform(-2, 2, model.nu), rng.uniform(-1, 1, model.na))


def mujoco_at(m, d, q, v, ctrl, act):
    d.qpos[:], d.qvel[:], d.ctrl[:], d.act[:] = q, v, ctrl, act
    mujoco.mj_forward(m, d)
    return d


def test_actuators_and_tendons_equal_mujocos_own_computation():
    scene = rbody.from_mjcf(ARM)
    model = scene.multibody
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    assert (model.nu, model.na, model.ntendon) == (m.nu, m.na, m.ntendon) == (10, 4, 2)
    assert model.actuator_names == tuple(m.actuator(i).name for i in range(m.nu))
    # the compiler's damping ratio -> kv (joint and tendon transmissions) and every other parameter
    np.testing.assert_allclose([a.biasprm for a in model.layout.actuators], m.actuator_biasprm[:, :3], rtol=1e-13,
                               atol=0)
    np.testing.assert_allclose([a.gainprm for a in model.layout.actuators], m.actuator_gainprm[:, :3], rtol=0, atol=0)
    rng = np.random.default_rng(0)
    for q, v, ctrl, act in random_states(model, rng, 6):
        theirs = mujoco_at(m, d, q, v, ctrl, act)
        mine = model.actuation(q, v, ctrl, act)
        scale = max(1.0, np.max(np.abs(theirs.qfrc_actuator)))
        assert np.max(np.abs(mine["qfrc"] - theirs.qfrc_actuator)) < 1e-14 * scale
        assert np.max(np.abs(mine["force"] - theirs.actuator_force)) < 1e-14 * scale
        assert np.max(np.abs(mine["act_dot"] - theirs.act_dot)) < 1e-14 * max(1.0, np.max(np.abs(theirs.act_dot)))
        assert np.max(np.abs(mine["length"] - theirs.actuator_length)) < 1e-15
        assert np.max(np.abs(mine["velocity"] - theirs.actuator_velocity)) < 1e-14
        tendons = model.tendons(q, v)
        assert np.max(np.abs(tendons["length"] - theirs.ten_length)) < 1e-15
        # as the actuators' velocities above (1e-14): point velocities now come from the tree's own origin (main's
        # far-from-origin work), which rounds a spatial tendon's sum of O(1) terms differently (measured 1.2e-15)
        assert np.max(np.abs(tendons["velocity"] - theirs.ten_velocity)) < 1e-14
        assert np.max(np.abs(model.passive_forces(q, v) - theirs.qfrc_passive)) < 1e-14
        assert np.max(np.abs(model.actuator_forces(q, v, ctrl, act) - theirs.qfrc_actuator)) < 1e-14 * scale
        qacc = model.forward_dynamics(q, v, ctrl=ctrl, act=act)
        assert np.max(np.abs(qacc - theirs.qacc)) < 1e-11 * np.max(np.abs(theirs.qacc))


def test_batches_of_states_and_controls_give_the_single_results():
    model = rbody.from_mjcf(ARM).multibody
    states = list(random_states(model, np.random.default_rng(1), 4))
    q, v, ctrl, act = (np.stack([s[k] for s in states]).reshape(2, 2, -1) for k in range(4))
    batch = model.actuation(q, v, ctrl, act)
    assert batch["qfrc"].shape == (2, 2, model.nv) and batch["moment"].shape == (2, 2, model.nu, model.nv)
    single = model.actuation(q[1, 0], v[1, 0], ctrl[1, 0], act[1, 0])
    for name, value in single.items():
        np.testing.assert_array_equal(batch[name][1, 0], value)
    # the inverse dynamics invert the forward dynamics with the actuators at the same controls
    a = model.forward_dynamics(q, v, ctrl=ctrl, act=act)
    tau = model.inverse_dynamics(q, v, a, ctrl=ctrl, act=act)
    assert np.max(np.abs(tau)) < 1e-9 * np.max(np.abs(model.mass_matrix(q)))


def test_to_mjcf_writes_general_actuators_and_tendons_that_mujoco_reads_the_same():
    scene = rbody.from_mjcf(ARM)
    text = rbody.to_mjcf(scene)
    assert "<general" in text and "<spatial" in text and "<fixed" in text
    original, exported = (mujoco.MjModel.from_xml_string(x) for x in (ARM, text))
    exported.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    d1, d2 = mujoco.MjData(original), mujoco.MjData(exported)
    for q, v, ctrl, act in random_states(scene.multibody, np.random.default_rng(2), 3):
        mujoco_at(original, d1, q, v, ctrl, act)
        mujoco_at(exported, d2, q, v, ctrl, act)
        assert np.max(np.abs(d1.qfrc_actuator - d2.qfrc_actuator)) < 1e-13 * max(1, np.max(np.abs(d1.qfrc_actuator)))
        assert np.max(np.abs(d1.qfrc_passive - d2.qfrc_passive)) < 1e-13
        np.testing.assert_array_equal(d1.act_dot, d2.act_dot)


# ----- flags, options, keyframes -----------------------------------------------------------------------------

def flagged(flags: str = "", option: str = "") -> str:
    return ARM.replace('<option timestep="0.002" integrator="RK4"><flag contact="disable"/></option>',
                       f'<option timestep="0.002" integrator="RK4" {option}><flag contact="disable" {flags}/></option>')


@pytest.mark.parametrize("flags, option, note", [
    ('actuation="disable"', "", "actuation"),
    ('clampctrl="disable"', "", "clampctrl"),
    ("", 'actuatorgroupdisable="0"', "actuatorgroupdisable"),
    ('spring="disable" damper="disable"', "", "tendon stiffness"),
])
def test_option_flags_are_obeyed_as_mujoco_obeys_them_and_noted(flags, option, note):
    xml = flagged(flags, option)
    scene = rbody.from_mjcf(xml)
    assert any(note in line for line in scene.import_notes), scene.import_notes
    model = scene.multibody
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    for q, v, ctrl, act in random_states(model, np.random.default_rng(3), 3):
        theirs = mujoco_at(m, d, q, v, 3 * ctrl, act)
        np.testing.assert_allclose(model.actuator_forces(q, v, 3 * ctrl, act), theirs.qfrc_actuator, rtol=0,
                                   atol=1e-13 * max(1, np.max(np.abs(theirs.qfrc_actuator))))
        np.testing.assert_allclose(model.passive_forces(q, v), theirs.qfrc_passive, rtol=0, atol=1e-14)


def test_a_keyframes_act_and_ctrl_start_the_run():
    xml = ARM.replace("</mujoco>", '<keyframe><key name="k" act="0.1 0.2 0.3 0.4" ctrl="1 2 3 4 5 6 7 8 9 10"/>'
                                   "</keyframe></mujoco>")
    scene = rbody.from_mjcf(xml, keyframe="k")
    np.testing.assert_array_equal(scene.act0, [0.1, 0.2, 0.3, 0.4])
    np.testing.assert_array_equal(scene.ctrl0, np.arange(1.0, 11.0))
    run = rbody.simulate(scene, dt=0.002, t_end=0.004, method="rk4")
    np.testing.assert_array_equal(run["ctrl"][0], np.arange(1.0, 11.0))
    np.testing.assert_array_equal(run["act"][0], [0.1, 0.2, 0.3, 0.4])


# ----- closed forms -----------------------------------------------------------------------------------------

def rotor(inertia: float, actuators, gravity: float = 0.0) -> Layout:
    """A body turning about a vertical hinge (gravity does no work): I theta'' = torque."""
    body = Body("rotor", Inertia(1.0, (0.0, 0.0, 0.0), np.diag([inertia, inertia, inertia])))
    return Layout(bodies=(body,), joints=(Joint("hinge", "hinge", "rotor", axis=(0, 0, 1)),), actuators=actuators)


def test_a_position_servo_is_a_damped_oscillator_of_known_frequency_and_decay():
    inertia, kp, kv, target = 0.2, 50.0, 1.2, 0.7
    servo = Actuator("servo", "hinge", bias="affine", gainprm=(kp, 0, 0), biasprm=(0, -kp, -kv))
    scene = Scene.from_layout(rotor(inertia, (servo,)), t_end=3.0)
    run = rbody.simulate(scene, dt=1e-3, method="rk4", ctrl=[target])
    # I x'' + kv x' + kp x = 0 for x = theta - target: x = -target e^{-zeta w t} (cos wd t + zeta w / wd sin wd t)
    w = math.sqrt(kp / inertia)
    zeta = kv / (2 * math.sqrt(kp * inertia))
    wd = w * math.sqrt(1 - zeta**2)
    t = run.t
    exact = target - target * np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    assert np.max(np.abs(run["qpos"][:, 0] - exact)) < 1e-9
    np.testing.assert_allclose(run["actuator_force"][:, 0], kp * (target - run["qpos"][:, 0]) - kv * run["qvel"][:, 0],
                               rtol=0, atol=1e-12)


def test_a_motor_on_a_free_body_gives_force_t_over_m_and_torque_t_over_i():
    inertia = np.diag([0.3, 0.5, 0.7])
    body = Body("box", Inertia(2.0, (0.0, 0.0, 0.0), inertia))
    push = Actuator("push", "free", gear=(1, 0, 0, 0, 0, 0))           # world force along x
    turn = Actuator("turn", "free", gear=(0, 0, 0, 0, 0, 1))           # body-frame torque about z, a principal axis
    layout = Layout(bodies=(body,), joints=(Joint("free", "free", "box"),), actuators=(push, turn))
    scene = Scene.from_layout(layout, t_end=2.0, gravity=0.0)
    force, torque = 3.0, 0.35
    run = rbody.simulate(scene, dt=1e-3, method="rk4", ctrl=[force, torque])
    t = run.t
    np.testing.assert_allclose(run["qvel"][:, 0], force * t / 2.0, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(run["qvel"][:, 5], torque * t / 0.7, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(run["qpos"][:, 0], force * t**2 / 4.0, rtol=1e-12, atol=1e-13)
    angle = torque * t**2 / (2 * 0.7)  # about z: quat (cos a/2, 0, 0, sin a/2)
    np.testing.assert_allclose(run["qpos"][:, 3], np.cos(angle / 2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(run["qpos"][:, 6], np.sin(angle / 2), rtol=0, atol=1e-12)


def test_a_filter_follows_its_step_response_and_mujocos_rk4_with_filterexact_does_not():
    """act' = (u - act)/tau: act = u (1 - e^{-t/tau}). rbody's rk4 integrates that equation (filter and filterexact
    alike); MuJoCo's RK4 advances a filterexact activation by the exact one-step formula applied to the RK4-averaged
    rate, act + <act'> tau (1 - e^{-h/tau}), which is not the solution: a finding, measured here."""
    tau, u, dt = 0.05, 0.8, 0.01
    xml = f"""<mujoco><option timestep="{dt}" integrator="RK4" gravity="0 0 0"/><worldbody><body>
      <joint name="j" axis="0 0 1"/><geom size="0.1"/></body></worldbody>
      <actuator><general joint="j" dyntype="filterexact" dynprm="{tau}"/></actuator></mujoco>"""
    scene = rbody.from_mjcf(xml, t_end=0.5)
    run = rbody.simulate(scene, dt=dt, method="rk4", ctrl=[u])
    exact = u * (1 - np.exp(-run.t / tau))
    rbody_error = np.max(np.abs(run["act"][:, 0] - exact))
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.ctrl[:] = u
    acts = [d.act[0]]
    for _ in range(run.t.size - 1):
        mujoco.mj_step(m, d)
        acts.append(d.act[0])
    mujoco_error = np.max(np.abs(np.array(acts) - exact))
    assert rbody_error < 1e-5       # measured 4.6e-6; 2.7e-7 at h/2 (fourth order)
    assert mujoco_error > 1e-2      # measured 3.2e-2; 1.5e-2 at h/2, 7.5e-3 at h/4 (first order in h)
    assert mujoco_error > 1000 * rbody_error


# ----- the description's own checks and MJCF refusals --------------------------------------------------------

def test_layout_values_are_checked_before_any_work():
    with pytest.raises(ValueError, match="dynamics='muscle'"):
        Actuator("a", "j", dynamics="muscle")
    with pytest.raises(ValueError, match="ctrlrange"):
        Actuator("a", "j", ctrlrange=(1, -1))
    with pytest.raises(ValueError, match="gear"):
        Actuator("a", "j", gear=(1, 2, 3, 4, 5, 6, 7))
    with pytest.raises(ValueError, match="fixed tendon needs joints"):
        Tendon("t", "fixed")
    with pytest.raises(ValueError, match="two sites"):
        Tendon("t", "spatial", sites=(("b", (0, 0, 0)),))
    base = rotor(1.0, ())
    with pytest.raises(ValueError, match="target='nope' is not a joint"):
        rbody.Multibody(Layout(base.bodies, base.joints, actuators=(Actuator("a", "nope"),)))
    with pytest.raises(ValueError, match="takes 1 gear"):
        rbody.Multibody(Layout(base.bodies, base.joints, actuators=(Actuator("a", "hinge", gear=(1, 1)),)))
    with pytest.raises(ValueError, match="two actuators"):
        rbody.Multibody(Layout(base.bodies, base.joints, actuators=(Actuator("a", "hinge"), Actuator("a", "hinge"))))
    with pytest.raises(ValueError, match="joint 'x' is not a joint"):
        rbody.Multibody(Layout(base.bodies, base.joints, tendons=(Tendon("t", joints=(("x", 1.0),)),)))


BODY = '<body name="b" pos="0 0 1"><joint name="j" axis="0 1 0"/><geom size="0.1"/><site name="s" pos="0 0 0.1"/>'
REFUSED = [
    ('<actuator>\n<muscle joint="j"/></actuator>', r"line 2, <muscle>: muscle actuators"),
    ('<actuator>\n<cylinder joint="j"/></actuator>', r"line 2, <cylinder>: cylinder actuators"),
    ('<actuator>\n<adhesion body="b"/></actuator>', r"line 2, <adhesion>: adhesion"),
    ('<actuator>\n<motor site="s" refsite="s"/></actuator>', r"line 2, <motor>: a site transmission with refsite"),
    ('<actuator>\n<motor body="b"/></actuator>', r"line 2, <motor>: a body transmission"),
    ('<actuator>\n<general cranksite="s" slidersite="s" cranklength="1"/></actuator>', r"line 2, <general>: a cranksite"),
    ('<actuator>\n<general joint="j" dyntype="muscle"/></actuator>', r"line 2, <general>: dyntype=\"muscle\""),
    ('<actuator>\n<general joint="j" gaintype="user"/></actuator>', r"line 2, <general>: gaintype=\"user\""),
    ('<actuator>\n<position joint="j" damping="1"/></actuator>', r"line 2, <position>: actuator damping"),
    ('<actuator>\n<motor joint="j" delay="0.01"/></actuator>', r"line 2, <motor>: actuator delay"),
    ('<actuator>\n<motor joint="j" kp="3"/></actuator>', r"line 2, <motor>: unknown attribute 'kp'"),
    ('<actuator>\n<motor joint="nope"/></actuator>', r"line 2, <motor>: joint='nope' is not a joint"),
    ('<actuator>\n<position joint="j" kv="1" dampratio="1"/></actuator>', r"line 2, <position>: kv and dampratio"),
    ('<actuator>\n<plugin plugin="x"/></actuator>', r"line 2, <plugin>: actuator plugins"),
    ('<tendon>\n<spatial><site site="s"/><geom geom="g"/><site site="s"/></spatial></tendon>',
     r"line 2, <geom>: a spatial tendon's <geom>"),
    ('<tendon>\n<spatial><site site="s"/><pulley divisor="2"/><site site="s"/></spatial></tendon>',
     r"line 2, <pulley>"),
    ('<tendon>\n<fixed frictionloss="-1"><joint joint="j" coef="1"/></fixed></tendon>',
     r"line 2, <fixed>: frictionloss=-1.0: must be >= 0"),
    ('<tendon>\n<fixed armature="1"><joint joint="j" coef="1"/></fixed></tendon>', r"line 2, <fixed>: tendon armature"),
    ('<tendon>\n<spatial><site site="s"/><site site="nope"/></spatial></tendon>', r"line 2, <site>: site='nope'"),
]


@pytest.mark.parametrize("section, match", REFUSED)
def test_what_rbody_cannot_model_is_refused_with_file_line_and_reason(section, match):
    xml = f'<mujoco><option><flag contact="disable"/></option><worldbody>{BODY}</body></worldbody>{section}</mujoco>'
    with pytest.raises(MJCFError, match=match) as error:
        layout_from_mjcf(xml)
    assert "<string>" in str(error.value)


DRONE = """<mujoco><option timestep="0.01" density="1.225" viscosity="1.8e-5"><flag contact="disable"/></option>
<worldbody><body name="frame" pos="0 0 0.1"><freejoint/><geom type="box" size=".06 .027 .02" pos=".04 0 .02" mass="0.5"/>
  <geom type="ellipsoid" size=".13 .13 .01" pos="-.14 -.18 .05" mass=".25"/>
  <site name="thrust" pos="-.14 -.18 .05" euler="5 0 0"/>
  <body name="arm" pos="0.1 0 0"><joint name="j" axis="0 1 0"/><geom size="0.03" mass="0.1"/>
    <site name="tip" pos="0.05 0 0" euler="10 20 30"/></body></body></worldbody>
<actuator><motor name="rotor" site="thrust" gear="0 0 1 0 0 -.0201" ctrlrange="0 13"/>
  <motor name="wrench" site="tip" gear="0.1 0.2 0.3 0.01 0.02 0.03"/></actuator>
<keyframe><key qpos="0 0 .3 1 0 0 0 0.2" ctrl="3.2 0.5"/></keyframe></mujoco>"""


def test_site_transmissions_drive_a_drone_as_mujoco_drives_it():
    """A wrench at a site, in the site's axes (MuJoCo's site transmission without refsite): the forces, a run at
    the file's step with its own integrator, and the export."""
    scene = rbody.from_mjcf(DRONE, keyframe=0, t_end=1.0)
    model = scene.multibody
    m = mujoco.MjModel.from_xml_string(DRONE)
    d = mujoco.MjData(m)
    exported = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene))
    d2 = mujoco.MjData(exported)
    rng = np.random.default_rng(4)
    for q, v, ctrl, act in random_states(model, rng, 3):
        theirs = mujoco_at(m, d, q, v, ctrl, act)
        mine = model.actuation(q, v, ctrl)
        assert np.max(np.abs(mine["qfrc"] - theirs.qfrc_actuator)) < 1e-14 * max(1, np.max(np.abs(theirs.qfrc_actuator)))
        np.testing.assert_array_equal(mine["length"], theirs.actuator_length)
        assert np.max(np.abs(mine["velocity"] - theirs.actuator_velocity)) < 1e-14
        mujoco_at(exported, d2, q, v, ctrl, act)
        assert np.max(np.abs(d2.qfrc_actuator - theirs.qfrc_actuator)) < 1e-14
    run = rbody.simulate(scene, dt=0.01, method=scene.file_method)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    qpos = [d.qpos.copy()]
    for _ in range(100):
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
    assert np.max(np.abs(run["qpos"] - np.array(qpos))) < 1e-11
