"""MuJoCo's integrators as rbody methods (rbody.engine.mujoco_steps): mujoco_euler, implicitfast and implicit run a
file at its own step as MuJoCo runs it, to round-off; their records, order and stability limits."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

import rbody
from rbody import Actuator, Body, Inertia, Joint, Layout, Scene
from rbody.errors import SimulationError

CONTROL_TESTS = Path(__file__).parents[1] / "test_control.py"
ARM = CONTROL_TESTS.read_text().split('ARM = """')[1].split('"""')[0]  # the 3-link arm with servos and a tendon
FILE_METHODS = [("Euler", "mujoco_euler"), ("implicitfast", "implicitfast"), ("implicit", "implicit")]


def mujoco_qpos(xml: str, steps: int, ctrl, keyframe: int | None = None) -> np.ndarray:
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    if keyframe is not None:
        mujoco.mj_resetDataKeyframe(m, d, keyframe)
    qpos = [d.qpos.copy()]
    for k in range(steps):
        d.ctrl[:] = ctrl[k] if np.ndim(ctrl) == 2 else ctrl
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
    return np.array(qpos)


@pytest.mark.parametrize("integrator, method", FILE_METHODS)
def test_position_servos_on_a_3_link_arm_run_as_mujoco_runs_them_over_2_s(integrator, method):
    xml = ARM.replace('integrator="RK4"', f'integrator="{integrator}"')
    scene = rbody.from_mjcf(xml, t_end=2.0)
    assert scene.file_method == method
    steps, dt = 1000, scene.timestep
    schedule = np.array([[1.5 * np.sin(3 * t), 0.5 * np.cos(2 * t), 0.3, 0.5 * np.sin(t), np.sin(5 * t)]
                         for t in np.arange(steps) * dt])
    run = rbody.simulate(scene, dt=dt, method=scene.file_method, ctrl=schedule)
    theirs = mujoco_qpos(xml, steps, schedule)
    assert np.max(np.abs(run["qpos"] - theirs)) < 1e-13
    assert np.max(np.abs(theirs[-1] - theirs[0])) > 0.1


FREE = """<mujoco><option timestep="0.005" integrator="INTEGRATOR"><flag contact="disable"/></option>
<worldbody>
 <body name="lone" pos="0 0 1"><freejoint/><geom type="box" size="0.3 0.1 0.05"/></body>
 <body name="torso" pos="2 0 1"><freejoint/><geom type="box" size="0.2 0.15 0.1"/>
   <body name="arm" pos="0.2 0 0"><joint name="sh" type="ball" damping="0.1"/>
     <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/>
     <body name="fore" pos="0.3 0 0"><joint name="el" axis="0 1 0" damping="0.05"/>
       <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.03"/></body>
   </body>
 </body>
</worldbody>
<actuator><position joint="el" kp="20" kv="1"/><motor joint="sh" gear="0 0 1"/></actuator>
<keyframe><key qpos="0 0 1 1 0 0 0  2 0 1 1 0 0 0  1 0 0 0  0.2" qvel="0.1 0 0 3 1 0.5  0 0 0 1 2 -1  2 -1 0.5  1"/>
</keyframe></mujoco>"""


@pytest.mark.parametrize("integrator, method", FILE_METHODS)
def test_free_bodies_and_ball_joints_run_as_mujoco_runs_them(integrator, method):
    """A tumbling free body alone in its tree (implicitfast treats its block with the gyroscopic derivative) and a
    free torso carrying a ball-jointed arm; MuJoCo's quaternion integration, gravity, servos."""
    xml = FREE.replace("INTEGRATOR", integrator)
    scene = rbody.from_mjcf(xml, t_end=2.0, keyframe=0)
    run = rbody.simulate(scene, dt=0.005, method=method, ctrl=[0.5, 0.2])
    theirs = mujoco_qpos(xml, 400, np.array([0.5, 0.2]), keyframe=0)
    assert np.max(np.abs(run["qpos"] - theirs)) < 1e-12


def test_implicitfast_keeps_the_lone_bodys_gyroscopic_derivative_and_differs_from_euler_there():
    scene = rbody.from_mjcf(FREE.replace("INTEGRATOR", "implicitfast"), t_end=1.0, keyframe=0)
    fast = rbody.simulate(scene, dt=0.005, method="implicitfast", ctrl=[0.5, 0.2])
    euler = rbody.simulate(scene, dt=0.005, method="mujoco_euler", ctrl=[0.5, 0.2])
    assert np.max(np.abs(fast["qpos"][:, 3:7] - euler["qpos"][:, 3:7])) > 1e-4  # the schemes differ: the test sees


def test_a_planar_tree_runs_mujocos_integrators_on_the_3d_rows():
    """A damped double pendulum takes the planar path under rk4 and the 3-D rows under MuJoCo's Euler."""
    xml = """<mujoco><option timestep="0.002"/><worldbody>
      <body pos="0 0 1"><joint axis="0 1 0" damping="0.3"/><geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05"/>
        <body pos="0 0 -0.5"><joint axis="0 1 0" damping="0.1"/><geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.04"/>
      </body></body></worldbody><keyframe><key qpos="1.2 -0.4"/></keyframe></mujoco>"""
    scene = rbody.from_mjcf(xml, t_end=2.0, keyframe=0)
    from rbody.engine.planar import planar_rhs

    assert scene.native_model.rhs is planar_rhs
    run = rbody.simulate(scene, dt=0.002, method=scene.file_method)
    theirs = mujoco_qpos(xml, 1000, np.zeros(0), keyframe=0)
    assert np.max(np.abs(run["qpos"] - theirs)) < 1e-13


# ----- records, order, stability --------------------------------------------------------------------------

def servo_rotor(kp: float, kv: float, damping: float = 0.0) -> Scene:
    """A rotor of inertia 0.2 about a vertical hinge held by a position servo: w = sqrt(kp / I)."""
    body = Body("rotor", Inertia(1.0, (0.0, 0.0, 0.0), np.diag([0.2, 0.2, 0.2])))
    servo = Actuator("servo", "hinge", bias="affine", gainprm=(kp, 0, 0), biasprm=(0, -kp, -kv))
    layout = Layout(bodies=(body,), joints=(Joint("hinge", "hinge", "rotor", axis=(0, 0, 1), damping=damping),),
                    actuators=(servo,))
    return Scene.from_layout(layout, t_end=1.0, ctrl0=[1.0])


@pytest.mark.parametrize("method", ["mujoco_euler", "implicitfast", "implicit"])
def test_each_is_first_order(method):
    scene = servo_rotor(kp=20.0, kv=0.5, damping=0.2)
    reference = rbody.simulate(scene, dt=1e-3, method="rk4")["qpos"][-1, 0]
    errors = [abs(rbody.simulate(scene, dt=dt, method=method)["qpos"][-1, 0] - reference) for dt in (4e-3, 2e-3)]
    assert rbody.METHOD_ORDER[method] == 1
    assert 1.7 < errors[0] / errors[1] < 2.3, errors


def test_the_stability_check_reads_the_stiffness_not_the_implicit_damping():
    """w = sqrt(kp / I) = 100 rad/s: MuJoCo's integrators are refused beyond h = 2 / w; a damping ratio of 500 (kv
    = 2e4) makes rk4's rate 1e5 / s, but the implicit integrators run (and stay bounded) at h = 0.01."""
    stiff = servo_rotor(kp=2000.0, kv=0.0)
    with pytest.raises(SimulationError, match="beyond its estimated stability limit 0.02"):
        rbody.simulate(stiff, dt=0.025, method="mujoco_euler")
    rbody.simulate(stiff, dt=0.015, method="mujoco_euler")
    damped = servo_rotor(kp=20.0, kv=2e4)
    with pytest.raises(SimulationError, match="stability limit"):
        rbody.simulate(damped, dt=0.01, method="rk4")
    run = rbody.simulate(damped, dt=0.01, method="implicitfast")
    assert np.all(np.abs(run["qpos"]) <= 1.0 + 1e-12)  # creeps towards the target without overshoot


def implicit_limit(w: float, c: float) -> float:
    """The largest stable step of semi-implicit Euler on q'' = -w^2 q - c q' with the damping implicit: the
    map's trace 1 + a - h^2 w^2 a and determinant a = 1 / (1 + h c) meet Jury's bound at h^2 w^2 = 4 + 2 h c."""
    return (c + math.sqrt(c * c + 4 * w * w)) / (w * w)


def explicit_limit(w: float, c: float) -> float:
    """The same with the damping explicit: trace 2 - h c - h^2 w^2, determinant 1 - h c: h^2 w^2 = 4 - 2 h c."""
    return (math.sqrt(c * c + 4 * w * w) - c) / (w * w)


@pytest.mark.parametrize("method, kv, damping, limit", [
    ("implicitfast", 60.0, 0.0, implicit_limit),    # kv implicit under implicitfast
    ("implicit", 60.0, 0.0, implicit_limit),
    ("mujoco_euler", 0.0, 60.0, implicit_limit),    # the joint's damping implicit under Euler
    ("mujoco_euler", 60.0, 0.0, explicit_limit),    # an actuator's kv explicit under Euler
    ("implicitfast", 0.0, 0.0, lambda w, c: 2 / w),
])
def test_the_stability_limit_of_a_damped_servo_is_the_closed_form(method, kv, damping, limit):
    """A servo of w = sqrt(kp / I) = 10 rad/s, damped by c = 60 / I = 300 / s: the limit differs from 2 / w by the
    damping each integrator solves for (rbody.engine.mujoco_stability), and a run just within it decays (near the
    limit the map is far from normal: the swing about the target first exceeds its start)."""
    scene = servo_rotor(kp=20.0, kv=kv, damping=damping)
    w, c = math.sqrt(20.0 / 0.2), (kv + damping) / 0.2
    expected = limit(w, c)
    assert math.isclose(rbody.stability.stability_limit(scene, method), expected, rel_tol=1e-6)
    assert expected != pytest.approx(2 / w, rel=0.1) or c == 0.0
    swing = np.abs(rbody.simulate(scene, t_end=400 * expected, dt=0.99 * expected, method=method)["qpos"][:, 0] - 1)
    quarter = len(swing) // 4
    if c > 0.0:  # a damped mode decays at any stable step (an undamped one keeps a bounded, sampled, swing)
        assert np.max(swing[-quarter:]) < np.max(swing[:quarter])


@pytest.mark.parametrize("method", ["mujoco_euler", "implicitfast", "implicit"])
def test_a_planar_family_does_not_offer_mujocos_integrators(method):
    """A chapter family that runs a planar tree inside its own model (a chain of three rods on the planar kernels)
    cannot hand its planar row to MuJoCo's one-step maps, which read the 3-D engine's rows: it does not list them
    and refuses them with the reason (it once stepped the planar row as a tree's and never returned)."""
    chain = rbody.scenes.pendulum_chain(3, theta0=[0.6, 0.4, 0.2], t_end=0.2)
    assert method not in chain.methods
    with pytest.raises(rbody.errors.MethodNotApplicable, match=method):
        rbody.simulate(chain, dt=0.1, method=method)
