"""Actuators on a constrained tree (a servo arm with its stops, the common case): the constraint layer's smooth forces
include the actuators' at the controls held through each step, the tendons', gravity compensation and fluid
forces, and the activations of actuators with dynamics are part of its state; every form of ctrl reaches it
(MuJoCo's integrators on a constrained tree: tests/rbody/test_constrained_mujoco_steps.py).

Closed forms: a motor pushing a rod into its stop holds it there, the stop's force equal to the motor's torque
minus gravity's; a position servo driving a rod past its stop holds it there with the force kp (u - hi) minus
gravity's; a rod under full gravity compensation swung by a tendon spring is a harmonic oscillator."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

import rbody
from rbody import Actuator, Body, Inertia, Joint, Layout, Scene, Tendon, prepare, simulate
from rbody.errors import MethodNotApplicable

G = 9.81
M, L = 1.0, 1.0                 # a uniform rod hanging from its end along -z, on a hinge about y
INERTIA = M * L**2 / 3          # about the hinge [kg m^2]
MGL = M * G * L / 2             # gravity's torque at 90 degrees [N m]: -MGL sin(theta)
HIGH = 0.5                      # the upper stop [rad]


def rod_body(gravcomp: float = 0.0) -> Body:
    moment = M * L**2 / 12
    return Body("rod", Inertia(M, (0.0, 0.0, -L / 2), np.diag([moment, moment, 1e-6 * moment])), gravcomp=gravcomp)


def rod_scene(actuators=(), tendons=(), gravcomp=0.0, qpos0=0.0, low=-1.0, high=HIGH, t_end=3.0, **scene) -> Scene:
    """The rod on its hinge (range (low, high), starting at rest at qpos0), with `actuators` and `tendons`; scene:
    Scene.from_layout's other arguments (a batch: qpos0 there is given as start=)."""
    if "start" in scene:
        scene["qpos0"] = scene.pop("start")
    hinge = Joint("h", "hinge", "rod", axis=(0, 1, 0), qpos0=qpos0, range=(low, high))
    layout = Layout(bodies=(rod_body(gravcomp),), joints=(hinge,), actuators=tuple(actuators), tendons=tuple(tendons))
    return Scene.from_layout(layout, t_end=t_end, **scene)


def upper_force(run) -> np.ndarray:
    """The upper stop's force (T,) [N m] (the Lagrange multiplier of its row: pushes the joint back, >= 0)."""
    rows = run.meta["constraint_rows"]
    return run["constraint_force"][:, rows.index(("limit", "h.upper", 0))]


MOTOR = Actuator("motor", "h")  # torque = ctrl [N m] (gear 1, gain 1)


@pytest.mark.parametrize("method", ["rk4", "moreau"])
def test_motor_pushing_a_rod_into_its_stop_holds_it_there_with_motor_minus_gravity(method):
    torque = 5.0
    run = simulate(rod_scene([MOTOR]), dt=1e-3, method=method, ctrl=[torque])
    theta = run["qpos"][:, 0]
    assert theta.max() <= HIGH + 1e-12                      # never past the stop beyond round-off
    settled = run.t > 1.0
    np.testing.assert_allclose(theta[settled], HIGH, rtol=0, atol=1e-12)
    np.testing.assert_allclose(run["qvel"][settled, 0], 0.0, rtol=0, atol=1e-9)
    expected = torque - MGL * math.sin(HIGH)                 # contact torque = motor torque - gravity's
    np.testing.assert_allclose(upper_force(run)[settled], expected, rtol=1e-9)
    np.testing.assert_allclose(run["actuator_force"][:, 0], torque, rtol=0, atol=0)
    np.testing.assert_allclose(run["ctrl"][:, 0], torque, rtol=0, atol=0)
    if method == "rk4":
        assert run.meta["impacts"] == 1 and run["active_limits"][-1, 1]


def test_a_motor_too_weak_to_swing_the_rod_to_its_stop_never_reaches_it():
    """Released from rest, the rod under a constant motor torque T swings up to the angle where the motor's work
    equals the weight's rise, T theta = m g (L/2) (1 - cos theta) (0.437 rad for T = 0.45 m g (L/2) sin(hi)), short of
    the stop, which stays free; kinetic + gravity energy less the motor's work is constant (nothing dissipates)."""
    from scipy.optimize import brentq

    torque = 0.45 * MGL * math.sin(HIGH)
    run = simulate(rod_scene([MOTOR]), dt=1e-3, ctrl=[torque])
    turning = brentq(lambda th: torque * th - MGL * (1 - math.cos(th)), 0.1, HIGH)
    assert run["qpos"][:, 0].max() < HIGH and not run["active_limits"][:, 1].any()
    assert run["qpos"][:, 0].max() == pytest.approx(turning, abs=1e-5)  # sampled near the turning point
    assert run.meta["events"] == 0
    work = torque * run["qpos"][:, 0]                          # the motor's work so far [J]
    assert np.ptp(run["energy"] - work) < 1e-10              # kinetic + gravity - motor work is constant


SERVO_XML = """
<mujoco model="servo_rod">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.001" integrator="RK4"><flag contact="disable"/></option>
  <worldbody>
    <body name="rod">
      <joint name="h" axis="0 1 0" range="-1 {high}"/>
      <inertial pos="0 0 -0.5" mass="1" diaginertia="{moment} {moment} {small}"/>
    </body>
  </worldbody>
  <actuator><position name="servo" joint="h" kp="{kp}" kv="{kv}"/></actuator>
</mujoco>
"""
KP, KV, TARGET = 40.0, 4.0, 1.2


def servo_file(tmp_path) -> str:
    moment = M * L**2 / 12
    path = tmp_path / "servo_rod.xml"
    path.write_text(SERVO_XML.format(high=HIGH, moment=moment, small=1e-6 * moment, kp=KP, kv=KV))
    return str(path)


def test_position_servo_driving_past_its_stop_is_held_by_the_stop_as_the_closed_form_and_mujoco_say(tmp_path):
    """A position servo aimed at 1.2 rad on a rod whose stop is at 0.5 rad: rbody holds the rod at the stop with the
    force kp (u - hi) - m g (L/2) sin(hi) (the servo's pull minus gravity's); MuJoCo's soft limit lets the rod pass
    the stop a little and reaches nearly the same force at rest (its equilibrium at the penetration it settles at)."""
    path = servo_file(tmp_path)
    scene = rbody.from_mjcf(path, t_end=3.0)
    run = simulate(scene, dt=1e-3, method="rk4", ctrl=[TARGET])
    theta = run["qpos"][:, 0]
    assert theta.max() <= HIGH + 1e-12
    settled = run.t > 2.0
    np.testing.assert_allclose(theta[settled], HIGH, rtol=0, atol=1e-12)
    expected = KP * (TARGET - HIGH) - MGL * math.sin(HIGH)
    np.testing.assert_allclose(upper_force(run)[settled], expected, rtol=1e-9)
    # MuJoCo, on the same file: past the stop (soft), then at rest near it, with about the same constraint force
    m = mujoco.MjModel.from_xml_path(path)
    d = mujoco.MjData(m)
    deepest = 0.0
    for _ in range(3000):
        d.ctrl[:] = TARGET
        mujoco.mj_step(m, d)
        deepest = max(deepest, d.qpos[0] - HIGH)
    assert 0 < deepest < 0.05                                 # MuJoCo's limit is soft: it passes the stop
    assert abs(d.qvel[0]) < 1e-3 and abs(d.qpos[0] - HIGH) < 0.01
    mujoco_force = -d.qfrc_constraint[0]                      # the stop pushes the joint back (negative qfrc)
    at_rest = KP * (TARGET - d.qpos[0]) - MGL * math.sin(d.qpos[0])  # MuJoCo's own equilibrium at its angle
    assert mujoco_force == pytest.approx(at_rest, rel=1e-3)
    assert mujoco_force == pytest.approx(expected, rel=0.02)  # the rigid limit's force, to MuJoCo's penetration


def test_every_form_of_ctrl_reaches_a_constrained_tree_and_prepared_runs_equal_simulate():
    """A schedule and a callable giving the same controls give the same run; prepare(ctrl=) and PreparedRun.run(ctrl=)
    equal simulate(ctrl=) bit for bit."""
    scene = rod_scene([MOTOR], t_end=1.0)
    steps = 1000
    schedule = 3.0 + 2.0 * np.sin(np.arange(steps) * 1e-3 * 7.0)[:, None]

    def policy(t, qpos, qvel):
        return [3.0 + 2.0 * math.sin(round(t / 1e-3) * 1e-3 * 7.0)]

    by_schedule = simulate(scene, dt=1e-3, ctrl=schedule)
    by_callable = simulate(scene, dt=1e-3, ctrl=policy)
    np.testing.assert_array_equal(by_schedule["qpos"], by_callable["qpos"])
    np.testing.assert_array_equal(by_schedule["ctrl"][:-1, 0], schedule[:, 0])
    assert by_schedule["qpos"][:, 0].max() <= HIGH + 1e-12 and by_schedule.meta["impacts"] >= 1
    prepared = prepare(scene, dt=1e-3)
    np.testing.assert_array_equal(prepared.run(ctrl=schedule)["qpos"], by_schedule["qpos"])
    np.testing.assert_array_equal(prepare(scene, dt=1e-3, ctrl=schedule).run()["qpos"], by_schedule["qpos"])
    constant = simulate(scene, dt=1e-3, ctrl=[5.0])
    np.testing.assert_array_equal(prepared.run(ctrl=[5.0])["qpos"], constant["qpos"])
    np.testing.assert_array_equal(prepared.run()["qpos"], simulate(scene, dt=1e-3)["qpos"])  # ctrl0 = 0
    moreau = simulate(scene, dt=1e-3, method="moreau", ctrl=schedule)
    np.testing.assert_array_equal(prepare(scene, dt=1e-3, method="moreau").run(ctrl=policy)["qpos"], moreau["qpos"])


def test_tendon_spring_under_gravity_compensation_swings_as_a_harmonic_oscillator_within_its_stops():
    """Gravity compensated fully (gravcomp = 1) and a fixed tendon spring of stiffness k on the hinge: I theta'' =
    -k theta, theta = theta0 cos(w t), w = sqrt(k / I); the stops (wider than the swing) hold nothing, but the tree
    runs through the constraint layer, whose smooth forces must carry the tendon's and gravity compensation's."""
    k, theta0 = 2.0, 0.3
    tendon = Tendon("t", joints=(("h", 1.0),), stiffness=k, springlength=(0.0, 0.0))
    scene = rod_scene(tendons=[tendon], gravcomp=1.0, qpos0=theta0, low=-0.4, high=0.4, t_end=2.0)
    run = simulate(scene, dt=1e-3)
    w = math.sqrt(k / INERTIA)
    np.testing.assert_allclose(run["qpos"][:, 0], theta0 * np.cos(w * run.t), rtol=0, atol=1e-9)
    assert run.meta["events"] == 0


def test_methods_the_constraint_layer_does_not_run_are_refused_saying_which_do():
    scene = rod_scene([MOTOR])
    for method in ("gauss6", "verlet"):
        with pytest.raises(MethodNotApplicable, match="constraint layer runs rk4, moreau, mujoco_euler"):
            simulate(scene, dt=1e-3, method=method)
    with pytest.raises(ValueError, match="callable"):  # a batch runs one element at a time: give a schedule
        simulate(rod_scene([MOTOR], start=[[0.0], [0.1]]), dt=1e-3, ctrl=lambda t, q, v: [1.0])


def test_a_filtered_motor_pushes_the_rod_into_its_stop_its_activation_as_the_closed_form():
    """A motor behind a first-order filter (time constant tau): act = u (1 - exp(-t / tau)) whatever the rod does; it
    drives the rod into its stop, which then holds it with the force act - m g (L/2) sin(hi)."""
    tau, u = 0.1, 5.0
    filtered = Actuator("filtered", "h", dynamics="filter", dynprm=tau)
    run = simulate(rod_scene([filtered]), dt=1e-3, ctrl=[u])
    np.testing.assert_allclose(run["act"][:, 0], u * (1 - np.exp(-run.t / tau)), rtol=0, atol=1e-9)
    settled = run.t > 1.5
    np.testing.assert_allclose(run["qpos"][settled, 0], HIGH, rtol=0, atol=1e-12)
    expected = run["act"][settled, 0] - MGL * math.sin(HIGH)
    np.testing.assert_allclose(upper_force(run)[settled], expected, rtol=1e-8)
    moreau = simulate(rod_scene([filtered]), dt=1e-3, method="moreau", ctrl=[u])
    assert moreau["qpos"][:, 0].max() <= HIGH + 1e-12
    np.testing.assert_allclose(moreau["act"][-1, 0], u * (1 - math.exp(-3.0 / tau)), rtol=1e-6)


def test_an_actuated_arm_whose_stops_are_never_reached_runs_as_without_them(tmp_path):
    """The 3-link arm of tests/rbody/test_control.py (position servos, a filtered general actuator, an integrated-
    velocity servo with an activation range, a motor on a fixed tendon with springs and a force range) with ranges it
    never reaches runs through the constraint layer; rk4 there (every smooth force from the force elements) equals
    rk4 on the tree without ranges (rbody.engine.system) to round-off, under a control computed each step."""
    from .test_control import ARM, policy

    free = rbody.from_mjcf(ARM, t_end=1.0)
    limited_xml = ARM.replace('<joint name="j1" axis="0 1 0"/>', '<joint name="j1" axis="0 1 0" range="-3 3"/>')
    limited_xml = limited_xml.replace('<joint name="j2" axis="0 1 0"/>', '<joint name="j2" axis="0 1 0" range="-3 3"/>')
    limited = rbody.from_mjcf(limited_xml, t_end=1.0)
    assert limited.tree.constrained and not free.tree.constrained
    a = simulate(free, dt=0.002, method="rk4", ctrl=policy)
    b = simulate(limited, dt=0.002, method="rk4", ctrl=policy)
    assert b.meta["events"] == 0
    np.testing.assert_allclose(b["qpos"], a["qpos"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(b["act"], a["act"], rtol=0, atol=1e-10)
    np.testing.assert_allclose(b["actuator_force"], a["actuator_force"], rtol=0, atol=1e-9)


def test_an_error_estimate_under_a_schedule_holds_each_row_for_both_half_steps():
    """simulate(..., error_estimate=True) repeats the run at dt/2: a schedule's row k is then held for steps 2k and
    2k + 1, so the two runs see the same controls and the estimate is rk4's own error (the rotor's servo of the README:
    about 1e-10 rad at dt = 1 ms); the schedule as given would be half as long as the finer run needs."""
    rotor = Body("rotor", Inertia(1.0, (0, 0, 0), np.diag([0.2, 0.2, 0.2])))
    servo = Actuator("servo", "hinge", bias="affine", gainprm=(20.0, 0, 0), biasprm=(0, -20.0, -0.4))
    layout = Layout(bodies=(rotor,), joints=(Joint("hinge", "hinge", "rotor", axis=(0, 0, 1)),), actuators=(servo,))
    scene = Scene.from_layout(layout, t_end=1.0)
    schedule = np.where(np.arange(1000) < 500, 0.5, -0.5)[:, None]
    run = simulate(scene, dt=1e-3, method="rk4", ctrl=schedule, error_estimate=True)
    assert 0 < run.meta["error_estimate"]["qpos"] < 1e-8
