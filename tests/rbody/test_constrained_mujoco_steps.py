"""MuJoCo's integrators on a constrained tree (rbody.engine.constraints.stepping): the Moreau-Jean time-stepping with
the file's own integrator (mujoco_euler, implicitfast, implicit) as its free motion, so that a robot with stiff
position servos, joint limits and dry friction runs at its own step with its own scheme.

- With no constraint active a step is MuJoCo's step: a servo arm whose stops are never reached equals the same arm
  without stops under rbody's free-tree step bit for bit, and MuJoCo's mj_step to round-off, with a filterexact
  actuator's activation too.
- Where a constraint acts the result is the rigid limit's: a stiff servo driven past its stop, at a step explicit
  schemes cannot take, is held at the stop to round-off with the closed form's force kp (u - hi) - m g (L/2) sin(hi);
  a joint whose dry friction exceeds gravity's torque does not move at all.
- The stability check knows the scheme: an actuator's kv is explicit under mujoco_euler, implicit under implicitfast.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import rbody
from rbody import simulate
from rbody.errors import SimulationError

G = 9.81
ARM = """
<mujoco model="servo_arm">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{dt}" integrator="{integrator}"><flag contact="disable"/></option>
  <worldbody>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" axis="0 1 0" damping="0.5" {range1}/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04" mass="1"/>
      <body name="fore" pos="0.3 0 0">
        <joint name="elbow" axis="0 1 0" damping="0.2" frictionloss="{friction}" {range2}/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="0.7"/>
        <body name="hand" pos="0.3 0 0">
          <joint name="wrist" axis="1 0 0" damping="0.05" {range3}/>
          <geom type="box" size="0.03 0.05 0.02" mass="0.3"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position joint="shoulder" kp="{kp}" kv="{kv}"/>
    <position joint="elbow" kp="{kp}" kv="{kv}"/>
    <general joint="wrist" dyntype="filterexact" dynprm="0.05" gaintype="fixed" gainprm="0.01"/>
  </actuator>
</mujoco>"""
WIDE = ('range="-3 3"', 'range="-3 3"', 'range="-3 3"')   # stops the arm never reaches
CTRL = np.array([0.5, -0.4, 1.0])


def arm(integrator: str, ranges=WIDE, dt: float = 0.002, kp: float = 400.0, kv: float = 20.0,
        friction: float = 0.0) -> str:
    return ARM.format(dt=dt, integrator=integrator, range1=ranges[0], range2=ranges[1], range3=ranges[2], kp=kp,
                      kv=kv, friction=friction)


def mujoco_run(xml: str, ctrl: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(qpos (steps + 1, nq), act (steps + 1, na)) of MuJoCo's mj_step on the file under a constant control."""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.ctrl[:] = ctrl
    qpos, act = [d.qpos.copy()], [d.act.copy()]
    for _ in range(steps):
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
        act.append(d.act.copy())
    return np.array(qpos), np.array(act)


@pytest.mark.parametrize("integrator, method, kv", [("Euler", "mujoco_euler", 2.0), ("implicitfast", "implicitfast", 20.0),
                                                    ("implicit", "implicit", 20.0)])
def test_with_no_constraint_active_a_step_is_mujocos_step(integrator, method, kv):
    constrained = rbody.from_mjcf(arm(integrator, kv=kv), t_end=1.0)
    free = rbody.from_mjcf(arm(integrator, ranges=("", "", ""), kv=kv), t_end=1.0)
    assert constrained.multibody.nv == 3 and constrained.constraint_table is not None
    assert method in constrained.methods and free.constraint_table is None
    run = simulate(constrained, dt=0.002, method=method, ctrl=CTRL)
    assert "MuJoCo's" in run.meta["scheme"] and not run["active_limits"].any()
    np.testing.assert_array_equal(run["qpos"], simulate(free, dt=0.002, method=method, ctrl=CTRL)["qpos"])
    qpos, act = mujoco_run(arm(integrator, kv=kv), CTRL, 500)
    assert np.ptp(qpos[:, 0]) > 0.3                                    # the arm swings: the comparison says something
    np.testing.assert_allclose(run["qpos"], qpos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run["act"], act, rtol=0, atol=1e-14)  # filterexact, advanced as MuJoCo advances it


def test_a_callable_control_gives_the_run_a_schedule_gives():
    scene = rbody.from_mjcf(arm("implicitfast"), t_end=0.5)
    steps = 250
    schedule = CTRL + 0.3 * np.sin(np.arange(steps) * 0.002 * 9.0)[:, None]

    def policy(t, qpos, qvel):
        return CTRL + 0.3 * math.sin(round(t / 0.002) * 0.002 * 9.0)

    by_schedule = simulate(scene, dt=0.002, method="implicitfast", ctrl=schedule)
    np.testing.assert_array_equal(simulate(scene, dt=0.002, method="implicitfast", ctrl=policy)["qpos"],
                                  by_schedule["qpos"])


SERVO = """
<mujoco model="stiff_servo_rod">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="implicitfast"><flag contact="disable"/></option>
  <worldbody>
    <body name="rod">
      <joint name="h" axis="0 1 0" range="-1 {high}"/>
      <inertial pos="0 0 -0.5" mass="1" diaginertia="{moment} {moment} {small}"/>
    </body>
  </worldbody>
  <actuator><position name="servo" joint="h" kp="{kp}" dampratio="2"/></actuator>
</mujoco>"""
HIGH, TARGET, KP = 0.5, 1.2, 2.0e6   # a stiff servo: w = sqrt(kp / I) = 2449 rad/s, overdamped (dampratio 2)


def test_a_stiff_servo_driven_past_its_stop_is_held_there_at_the_files_own_step():
    """The rod (I = m L^2 / 3 about its hinge) on a servo of kp = 2e6 N m/rad, damping ratio 2, aimed past its stop:
    at the file's step 2 ms rk4 is refused by the stability check (the fast mode's rate (2 + sqrt 3) w = 9.1e3 /s,
    dt times it 18, beyond rk4's 2.83), while implicitfast (kv implicit: stable while h < (c + sqrt(c^2 + 4 w^2)) /
    w^2 = 3.5 ms, c = 4 w) runs; the stop holds the rod at hi to round-off with the force kp (u - hi) - m g (L/2) sin(hi). MuJoCo's soft
    limit on the same file lets the rod pass the stop (its depth is measured, not asserted equal)."""
    xml = SERVO.format(high=HIGH, moment=1.0 / 12.0, small=1e-7, kp=KP)
    scene = rbody.from_mjcf(xml, t_end=1.0)
    assert scene.file_method == "implicitfast"
    with pytest.raises(SimulationError, match="stability limit"):
        simulate(scene, dt=0.002, method="rk4", ctrl=[TARGET])
    run = simulate(scene, dt=0.002, method="implicitfast", ctrl=[TARGET])
    theta = run["qpos"][:, 0]
    assert theta.max() <= HIGH + 1e-12                                # never past the stop beyond round-off
    settled = run.t > 0.5
    np.testing.assert_allclose(theta[settled], HIGH, rtol=0, atol=1e-12)
    rows = run.meta["constraint_rows"]
    force = run["constraint_force"][:, rows.index(("limit", "h.upper", 0))]
    expected = KP * (TARGET - HIGH) - G * 0.5 * math.sin(HIGH)
    np.testing.assert_allclose(force[settled], expected, rtol=1e-9)
    _qpos, _act = mujoco_run(xml, np.array([TARGET]), 500)
    assert _qpos[:, 0].max() > HIGH                                   # MuJoCo's soft limit: past the stop


def test_dry_friction_stronger_than_gravity_holds_the_elbow_still_under_implicitfast():
    """The forearm and hand held out horizontally, the elbow's servo off (kp = kv = 0) and its frictionloss 5 % above
    the weight's torque about it: the elbow sticks exactly (0 rad moved over 1 s), its friction force equal to the
    weight's torque. MuJoCo's regularised friction lets it creep (measured)."""
    forearm, hand = 0.7 * 0.15, 0.3 * 0.3                            # m x (their centres from the elbow) [kg m]
    weight_torque = G * (forearm + hand)
    xml = arm("implicitfast", kp=0.0, kv=0.0, friction=1.05 * weight_torque)
    scene = rbody.from_mjcf(xml, t_end=1.0)
    # the upper arm rests on its upper stop at 0 (gravity turns it towards +y's positive angles)
    shoulder_held = rbody.from_mjcf(xml.replace('damping="0.5" range="-3 3"', 'range="-1 0"'), t_end=1.0)
    run = simulate(shoulder_held, dt=0.002, method="implicitfast", ctrl=np.zeros(3))
    assert np.max(np.abs(run["qpos"][:, :2])) <= 1e-15                # stuck, to round-off
    assert run["sticking"][1:, 0].all() and run["active_limits"][1:, 1].all()
    rows = run.meta["constraint_rows"]
    friction = run["constraint_force"][1:, rows.index(("friction", "elbow", 0))]
    np.testing.assert_allclose(np.abs(friction), weight_torque, rtol=1e-9)
    qpos, _act = mujoco_run(xml, np.zeros(3), 500)
    assert scene.multibody.nv == 3 and abs(qpos[-1, 1]) > 0.0           # MuJoCo's elbow creeps


def test_the_stability_check_knows_which_damping_each_integrator_takes_implicitly():
    """A servo's kv is explicit under mujoco_euler (MuJoCo's Euler makes only the joints' damping implicit) and
    implicit under implicitfast: with kv = 400 on links of about 0.03 kg m^2, Euler is refused at 2 ms and
    implicitfast runs."""
    scene = rbody.from_mjcf(arm("Euler", kv=400.0), t_end=0.1)
    with pytest.raises(SimulationError, match="mujoco_euler.*stability limit"):
        simulate(scene, dt=0.002, method="mujoco_euler", ctrl=CTRL)
    run = simulate(scene, dt=0.002, method="implicitfast", ctrl=CTRL)
    assert np.all(np.isfinite(run["qpos"]))


BALL = """
<mujoco model="thrown_ball">
  <option timestep="0.001" integrator="{integrator}"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" friction="0.3 0 0"/>
    <body name="ball" pos="0 0 0.1">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.1" mass="1" friction="0.3 0 0"/>
    </body>
  </worldbody>
  <keyframe><key qpos="0 0 0.1 1 0 0 0" qvel="2 0 0 0 0 0"/></keyframe>
</mujoco>"""


@pytest.mark.parametrize("integrator, method", [("Euler", "mujoco_euler"), ("implicitfast", "implicitfast"),
                                                ("implicit", "implicit")])
def test_a_sphere_thrown_sliding_rolls_at_five_sevenths_under_mujocos_integrators(integrator, method):
    """The chapter's slide-to-roll transition with the file's own integrator (a lone free body: implicitfast keeps its
    gyroscopic derivative): rolling from the step holding t* = 2 v0 / (7 mu g), at 5/7 v0 to round-off, the height r
    throughout (no sinking), as under moreau."""
    r, mu, v0, dt = 0.1, 0.3, 2.0, 1e-3
    scene = rbody.from_mjcf(BALL.format(integrator=integrator), t_end=0.5, keyframe=0)
    assert scene.file_method == method
    run = simulate(scene, dt=dt, method=method)
    v, spin, z = run["ball.velocity"][:, 0], run["ball.omega"][:, 1], run["ball.com"][:, 2]
    t_star = 2 * v0 / (7 * mu * G)
    rolling = np.abs(v - r * spin) <= 1e-12
    start = run.t[np.argmax(rolling)]
    assert t_star <= start <= t_star + dt and np.all(rolling[run.t >= start])
    np.testing.assert_allclose(v[run.t >= start], 5 / 7 * v0, rtol=0, atol=1e-12)
    assert np.abs(z - r).max() <= 1e-15
    np.testing.assert_allclose(run["contact_normal_force"][-1], [G], rtol=1e-12)


FINGERS = """
<mujoco model="coupled_fingers">
  <compiler angle="radian"/>
  <option timestep="0.001"><flag contact="disable"/></option>
  <worldbody>
    <body name="palm" pos="0 0 0.5">
      <joint name="wrist" axis="0 1 0" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.02" mass="0.3"/>
      <body name="finger_a" pos="0.1 0 0.02">
        <joint name="a" axis="0 1 0" damping="0.001"/>
        <geom type="capsule" fromto="0 0 0 0.04 0 0" size="0.004" mass="0.002"/>
      </body>
      <body name="finger_b" pos="0.1 0 -0.02">
        <joint name="b" axis="0 1 0" damping="0.001"/>
        <geom type="capsule" fromto="0 0 0 0.04 0 0" size="0.004" mass="0.002"/>
      </body>
    </body>
  </worldbody>
  <tendon>
    <fixed name="ta"><joint joint="a" coef="1"/></fixed>
    <fixed name="tb"><joint joint="b" coef="1"/></fixed>
  </tendon>
  <equality>{equality}</equality>
  <keyframe><key qvel="1 2 0"/></keyframe>
</mujoco>"""


def test_a_coupled_gripper_runs_at_its_own_step_its_stability_the_free_steps():
    """Two light fingers coupled by a tendon equality (a gripper's mimic, as in a planar manipulator's hand), Euler at
    the file's 1 ms: the time-stepping's stability is that of its free motion, the tree's own Euler step, not of the
    constrained motion's linearisation (whose derivative of the coupling force is large for light fingers): the rate
    equals the tree's without the equality, the run goes, and the coupling holds to round-off."""
    coupled = rbody.from_mjcf(FINGERS.format(equality='<tendon tendon1="tb" tendon2="ta" polycoef="0 -1 0 0 0"/>'),
                              t_end=0.5, keyframe=0)
    free = rbody.from_mjcf(FINGERS.format(equality=""), t_end=0.5, keyframe=0)
    assert coupled.constraint_table is not None and free.constraint_table is None
    np.testing.assert_allclose(coupled.native_model.rate("mujoco_euler"), free.native_model.rate("mujoco_euler"),
                               rtol=1e-9)
    run = simulate(coupled, dt=0.001, method="mujoco_euler")
    qpos = run["qpos"]
    np.testing.assert_allclose(qpos[:, 2], -qpos[:, 1], rtol=0, atol=1e-12)   # b = -a: the fingers close together
    assert np.ptp(qpos[:, 1]) > 1e-4                                          # they move: the check says something
