"""The control input of a run (rbody.control, simulate(..., ctrl=...)): held through every step as MuJoCo holds it,
so that rbody's rk4 and MuJoCo's RK4 under the same control sequence agree to round-off; every form of ctrl."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

import rbody

# A 3-link arm with a slide at its tip: position servos (one with a damping ratio), a filtered general actuator,
# an integrated-velocity servo with an activation range, a motor on a fixed tendon with springs and a force range.
ARM = """
<mujoco model="arm3">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002" integrator="RK4"><flag contact="disable"/></option>
  <default><joint damping="0.05"/></default>
  <worldbody>
    <body name="l1" pos="0 0 1"><joint name="j1" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <body name="l2" pos="0.4 0 0"><joint name="j2" axis="0 1 0"/><geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body name="l3" pos="0.3 0 0"><joint name="j3" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.03"/>
          <body name="s" pos="0.2 0 0"><joint name="s" type="slide" axis="1 0 0"/><geom type="sphere" size="0.04"/></body>
        </body></body></body>
  </worldbody>
  <tendon><fixed name="t" stiffness="3" damping="0.2"><joint joint="j1" coef="1"/><joint joint="j3" coef="0.5"/></fixed></tendon>
  <actuator>
    <position joint="j1" kp="50" kv="5" ctrlrange="-1 1"/>
    <position joint="j2" kp="30" dampratio="0.8"/>
    <general joint="j3" dyntype="filter" dynprm="0.05" gainprm="2" biastype="affine" biasprm="0 -3 -0.5"/>
    <intvelocity joint="s" kp="40" kv="4" actrange="-0.2 0.2"/>
    <motor tendon="t" gear="2" forcerange="-1 1"/>
  </actuator>
</mujoco>
"""
DT, STEPS = 0.002, 1000


def policy(t, qpos, qvel):
    """Controls that vary within the run and leave the ranges (the clamps are exercised)."""
    return np.array([1.5 * np.sin(3 * t), 0.5 * np.cos(2 * t), 0.3, 0.5 * np.sin(t), np.sin(5 * t)])


def mujoco_run(controls):
    """MuJoCo's RK4 at DT, controls(k, data) setting d.ctrl before step k; qpos, act of every step."""
    m = mujoco.MjModel.from_xml_string(ARM)
    d = mujoco.MjData(m)
    qpos, act = [d.qpos.copy()], [d.act.copy()]
    for k in range(STEPS):
        d.ctrl[:] = controls(k, d)
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
        act.append(d.act.copy())
    return np.array(qpos), np.array(act)


@pytest.fixture(scope="module")
def arm():
    return rbody.from_mjcf(ARM, t_end=STEPS * DT)


def test_rk4_under_a_callable_equals_mujocos_rk4_to_round_off_over_2_s(arm):
    seen = []

    def control(t, qpos, qvel):
        seen.append((t, qpos.shape, qvel.shape))
        return policy(t, qpos, qvel)

    run = rbody.simulate(arm, dt=DT, method="rk4", ctrl=control)
    qpos, act = mujoco_run(lambda k, d: policy(d.time, d.qpos, d.qvel))
    assert len(seen) == STEPS and seen[1] == (DT, (4,), (4,)) and seen[-1][0] == pytest.approx((STEPS - 1) * DT)
    assert np.max(np.abs(run["qpos"] - qpos)) < 1e-13
    assert np.max(np.abs(run["act"] - act)) < 1e-14
    assert np.max(np.abs(qpos[-1] - qpos[0])) > 0.1  # it moved


def test_rk4_under_an_array_equals_mujocos_rk4_and_the_same_callable_bit_for_bit(arm):
    schedule = np.array([policy(k * DT, None, None) for k in range(STEPS)])
    run = rbody.simulate(arm, dt=DT, method="rk4", ctrl=schedule)
    qpos, act = mujoco_run(lambda k, d: schedule[k])
    assert np.max(np.abs(run["qpos"] - qpos)) < 1e-13
    assert np.max(np.abs(run["act"] - act)) < 1e-14
    by_callable = rbody.simulate(arm, dt=DT, method="rk4", ctrl=lambda t, q, v: schedule[int(round(t / DT))])
    np.testing.assert_array_equal(run["qpos"], by_callable["qpos"])
    # the observables: the control held through the step that starts at each saved time, and the force it gives
    np.testing.assert_array_equal(run["ctrl"][:-1], schedule)
    np.testing.assert_array_equal(run["ctrl"][-1], schedule[-1])
    model = arm.multibody
    force = model.actuation(run["qpos"][500], run["qvel"][500], schedule[500], run["act"][500], timestep=DT)["force"]
    np.testing.assert_array_equal(run["actuator_force"][500], force)
    sparse = rbody.simulate(arm, dt=DT, method="rk4", ctrl=schedule, save_every=10)
    np.testing.assert_array_equal(sparse["qpos"], run["qpos"][::10])
    np.testing.assert_array_equal(sparse["ctrl"][:-1], schedule[::10])


def test_a_constant_control_runs_in_one_loop_and_equals_mujoco(arm):
    ctrl = np.array([0.4, -0.2, 0.3, 0.1, 0.5])
    run = rbody.simulate(arm, dt=DT, method="rk4", ctrl=ctrl)
    qpos, _ = mujoco_run(lambda k, d: ctrl)
    assert np.max(np.abs(run["qpos"] - qpos)) < 1e-13
    default = rbody.simulate(dataclasses.replace(arm, ctrl0=ctrl), dt=DT, method="rk4")  # a scene's ctrl0
    np.testing.assert_array_equal(default["qpos"], run["qpos"])


def test_batches_of_controls_give_each_elements_single_run(arm):
    rng = np.random.default_rng(0)
    batch = dataclasses.replace(arm, qpos0=arm.qpos0 + rng.uniform(-0.3, 0.3, (3, 4)), t_end=0.2)
    steps = 100
    constants = rng.uniform(-1, 1, (3, 5))
    schedules = rng.uniform(-1, 1, (steps, 3, 5))
    shared = rng.uniform(-1, 1, (steps, 5))
    for ctrl, row in ((constants, lambda b: constants[b]), (schedules, lambda b: schedules[:, b]),
                      (shared, lambda b: shared), (lambda t, q, v: constants, lambda b: constants[b])):
        run = rbody.simulate(batch, dt=DT, method="rk4", ctrl=ctrl)
        assert run["qpos"].shape == (steps + 1, 3, 4) and run["ctrl"].shape == (steps + 1, 3, 5)
        for b in range(3):
            single = rbody.simulate(batch.item(b), dt=DT, method="rk4", ctrl=row(b))
            np.testing.assert_array_equal(run["qpos"][:, b], single["qpos"])


@pytest.mark.parametrize("ctrl, match", [
    (np.zeros(4), r"ctrl has shape \(4,\): expected \(nu,\) = \(5,\)"),
    (np.zeros((3, 5)), r"ctrl has 3 rows: the run takes 10 steps"),
    (np.full(5, np.nan), "NaN or inf"),
    (np.zeros((10, 2, 5)), r"a schedule is \(n_steps, nu\) or \(n_steps, \*batch, nu\) with batch \(\)"),
    (lambda t, q, v: np.zeros(3), r"returned shape \(3,\) at step 0"),
    (lambda t, q, v: np.full(5, np.inf), "returned NaN or inf at step 0"),
])
def test_bad_controls_are_refused_naming_what_was_expected(arm, ctrl, match):
    with pytest.raises(ValueError, match=match):
        rbody.simulate(arm, dt=DT, t_end=10 * DT, method="rk4", ctrl=ctrl)


def test_a_control_for_a_scene_without_actuators_is_refused():
    pendulum = rbody.scenes.swinging_rod(1.0, theta0=0.5, t_end=0.1)
    with pytest.raises(ValueError, match="no actuators"):
        rbody.simulate(pendulum, dt=1e-3, ctrl=np.zeros(1))


def test_a_control_with_a_dask_client_is_refused_before_any_work(arm):
    with pytest.raises(ValueError, match="ctrl with client="):
        rbody.simulate(arm, dt=DT, t_end=10 * DT, method="rk4", ctrl=np.zeros(5), client=object())
